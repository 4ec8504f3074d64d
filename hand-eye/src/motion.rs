//! Whether a set of robot motions determines the hand-eye transform. Turning the gripper about a
//! single axis leaves the transform's translation along that axis (and its rotation about it
//! relative to the flag) unknown: the SCARA's shoulder, elbow and wrist yaw all turn about the
//! vertical, so the wrist must pitch or roll as well.

use crate::pose::log;
use nalgebra::{Isometry3, Vector3};

/// Relative rotations smaller than this (radians) say nothing of an axis.
pub const MIN_TURN_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;
/// Rotation axes within this angle (radians) of each other count as one.
pub const SAME_AXIS_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;
/// Fewest sightings: two relative motions about different axes need three poses.
pub const MIN_SIGHTINGS: usize = 3;

/// What motion is missing, if any.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MotionError {
    #[error(
        "{got} sightings are too few: the hand-eye transform needs at least {MIN_SIGHTINGS}, turned about two different axes"
    )]
    TooFew { got: usize },
    #[error(
        "the gripper never turned (by more than 5 deg) between sightings: turn it about two different axes, e.g. wrist pitch and roll"
    )]
    NoRotation,
    #[error(
        "every turn of the gripper between sightings is about one axis (about [{:.2}, {:.2}, {:.2}] in the base frame): the transform's translation along it is unknown; turn the gripper about another axis too (wrist pitch or roll)",
        axis.x, axis.y, axis.z
    )]
    OneAxis { axis: Vector3<f64> },
}

/// Checks that the gripper poses turn about at least two different axes.
pub fn check(base_from_gripper: &[Isometry3<f64>]) -> Result<(), MotionError> {
    if base_from_gripper.len() < MIN_SIGHTINGS {
        return Err(MotionError::TooFew { got: base_from_gripper.len() });
    }
    let mut axes: Vec<Vector3<f64>> = Vec::new();
    for (i, a) in base_from_gripper.iter().enumerate() {
        for b in &base_from_gripper[i + 1..] {
            let w = log(&(b.rotation * a.rotation.inverse()));
            if w.norm() > MIN_TURN_RAD {
                axes.push(w.normalize());
            }
        }
    }
    let first = *axes.first().ok_or(MotionError::NoRotation)?;
    let apart = |u: &Vector3<f64>| u.dot(&first).abs().min(1.0).acos() > SAME_AXIS_RAD;
    if axes.iter().any(apart) { Ok(()) } else { Err(MotionError::OneAxis { axis: first }) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn pose(rpy: [f64; 3], t: [f64; 3]) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(t[0], t[1], t[2]),
            UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
        )
    }

    #[test]
    fn yaw_alone_is_refused_and_says_which_axis() {
        let poses: Vec<_> = (0..6).map(|k| pose([0.0, 0.0, 0.3 * k as f64], [0.1 * k as f64, 0.2, 0.3])).collect();
        match check(&poses) {
            Err(MotionError::OneAxis { axis }) => assert!(axis.z.abs() > 0.99, "{axis}"),
            other => panic!("{other:?}"),
        }
        let msg = check(&poses).unwrap_err().to_string();
        assert!(msg.contains("pitch or roll"), "{msg}");
    }

    #[test]
    fn too_few_or_unturned_poses_are_refused_and_two_axes_pass() {
        assert_eq!(check(&[pose([0.0; 3], [0.0; 3])]), Err(MotionError::TooFew { got: 1 }));
        let still: Vec<_> = (0..5).map(|k| pose([0.0; 3], [0.1 * k as f64, 0.0, 0.0])).collect();
        assert_eq!(check(&still), Err(MotionError::NoRotation));
        let turned =
            [pose([0.0; 3], [0.0; 3]), pose([0.0, 0.0, 0.5], [0.1, 0.0, 0.0]), pose([0.4, 0.0, 0.0], [0.0, 0.1, 0.0])];
        assert_eq!(check(&turned), Ok(()));
    }
}
