//! The gimbal manager: each gimbal's task on the gimbal session
//! (`gimbal`), the plans it sends (`motion`), the status it streams
//! (`status`) at the intervals set for them (`rates`), and the re-aiming
//! of earth-frame aims as the vehicle moves (`reaim`).

pub mod gimbal;
pub mod motion;
pub mod rates;
pub mod reaim;
pub mod status;
