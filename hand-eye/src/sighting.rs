//! A sighting: what the robot and the camera each say of one pose of the flag.

use nalgebra::Isometry3;

/// One sighting of the flag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sighting {
    /// The gripper pose as the robot reports it (its joint encoders and kinematics).
    pub base_from_gripper: Isometry3<f64>,
    /// The flag's pose as vision measures it.
    pub cam_from_flag: Isometry3<f64>,
}
