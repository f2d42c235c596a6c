//! The gimbal manager's tasks: each gimbal's task on the gimbal session
//! (`gimbal`), the status every gimbal component streams (`status`), and
//! the re-aiming of earth-frame aims as the vehicle moves (`reaim`).

pub mod gimbal;
pub mod reaim;
pub mod status;
