//! The UMI-style arm, without any simulation: what the kinematics/path server knows.
//!
//! - [`arm`]: the arm from its URDF (links, collision primitives, joints and limits) and forward
//!   kinematics over the link tree.
//! - [`ik`]: the closed-form inverse kinematics (both elbow solutions, both wrist-pitch signs,
//!   limits respected; an unreachable pose is an error that says why).
//! - [`trajectory`]: rest-to-rest strokes under trapezoidal profiles within the URDF's velocity
//!   limits and derived acceleration limits.
//! - [`planner`]: the arm's link shapes against the scene's obstacles (parry), RRT-Connect with
//!   shortcutting, every segment checked densely.
//! - [`pick`]: the pick plan -- approach above the grasp, descend, close, lift, move above the
//!   bin, lower, release, retreat -- choosing among a model's grasps, their equivalent holds,
//!   depths and tilts.
//! - [`tool`]: tools held in the gripper (the calibration flag), from their URDF.
//!
//! It depends on neither `sim` nor `vision`.

pub mod arm;
pub mod ik;
pub mod pick;
pub mod planner;
pub mod tool;
pub mod trajectory;

pub use arm::{Arm, ArmError, Joints};
pub use ik::{Ik, IkError};
