//! The UMI-style arm, without any simulation: what the kinematics/path server knows.
//!
//! - [`arm`]: the arm from its URDF (links, collision primitives, joints and limits) and forward
//!   kinematics over the link tree.
//! - [`ik`]: the closed-form inverse kinematics (both elbow solutions, both wrist-pitch signs,
//!   limits respected; an unreachable pose is an error that says why).
//!
//! It depends on neither `sim` nor `vision`.

pub mod arm;
pub mod ik;
pub mod pick;
pub mod planner;
pub mod trajectory;

pub use arm::{Arm, ArmError, Joints};
pub use ik::{Ik, IkError};
