//! The earth frame: the vehicle's heading and place (`vehicle`), angles
//! turned between the earth and the mount (`geometry`), aims held in the
//! earth frame (`aim`), and MAVLink's gimbal frame on Sagebrush axes
//! (`frames`).

pub mod aim;
pub mod frames;
pub mod geometry;
pub mod vehicle;
