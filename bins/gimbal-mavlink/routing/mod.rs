//! Where a message goes: what each message (`inbox`) and command
//! (`command`) asks of which gimbal, the jobs a gimbal's task is handed
//! (`handle`) with the plans of a pitch/yaw request (`motion`) and the
//! status intervals asked (`rates`), who may command (`control`) and the
//! answers sent back (`answers`).

pub mod answers;
pub mod command;
pub mod control;
pub mod handle;
pub mod inbox;
pub mod motion;
pub mod rates;
