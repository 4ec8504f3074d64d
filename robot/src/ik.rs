//! Analytic inverse kinematics of the UMI RTX-style arm.
//!
//! The arm is a SCARA on a vertical slide: zed lifts the shoulder; shoulder, elbow and wrist yaw
//! turn about vertical axes; wrist pitch (about a horizontal axis through the wrist centre, the
//! tool hanging straight down at zero) and roll (about the tool axis) orient the gripper. So the
//! gripper orientation is `Rz(ψ)·Rx(π)·Ry(pitch)·Rz(roll)` with `ψ = shoulder + elbow + yaw`, and
//! the wrist centre lies a fixed tool length back along the approach axis from the tool centre
//! point. From the wrist centre: zed from its height, shoulder and elbow from the planar two-link
//! triangle (both elbow solutions); then pitch and ψ from the approach axis (both signs of pitch),
//! roll from the rest of the rotation, yaw = ψ - shoulder - elbow. The geometry constants are read
//! from the URDF, which [`Ik::new`] checks has this structure.

use crate::arm::{ARM_JOINTS, Arm, ArmError, JointKind, Joints};
use nalgebra::{Isometry3, Rotation3, UnitQuaternion, Vector2, Vector3};
use std::f64::consts::{PI, TAU};

/// Why a gripper pose cannot be reached.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IkError {
    #[error(
        "out of reach: the wrist centre is {distance_m:.3} m from the shoulder axis; the arm reaches {min_m:.3}..{max_m:.3} m"
    )]
    OutOfReach { distance_m: f64, min_m: f64, max_m: f64 },
    #[error("the tool would tilt {tilt_deg:.1} deg from straight down; wrist pitch allows {limit_deg:.1} deg")]
    TooTilted { tilt_deg: f64, limit_deg: f64 },
    #[error("joint `{joint}` would be at {value:.4}, outside its limits {lower:.4}..{upper:.4}")]
    JointLimit { joint: &'static str, value: f64, lower: f64, upper: f64 },
}

/// The arm's geometry as the closed-form solution needs it.
#[derive(Debug, Clone)]
pub struct Ik {
    /// Where the shoulder axis meets the base's xy plane.
    shoulder_xy: Vector2<f64>,
    upper_arm: f64,
    forearm: f64,
    /// Height of the wrist centre over the base when zed is 0.
    wrist_height_at_zero: f64,
    /// From the wrist centre to the tool centre point, along the approach axis.
    tool_length: f64,
    lower: Joints,
    upper: Joints,
}

const EXACT: f64 = 1e-9;

impl Ik {
    /// Reads the constants from the arm and checks that its joints have the structure the
    /// closed form assumes.
    pub fn new(arm: &Arm, file: &str) -> Result<Ik, ArmError> {
        let err = |message: String| ArmError::Urdf { file: file.to_string(), message };
        let expect_axis = [Vector3::z(), Vector3::z(), Vector3::z(), Vector3::z(), Vector3::y(), Vector3::z()];
        for k in 0..6 {
            let j = arm.joint(k);
            let want_kind = if k == 0 { JointKind::Prismatic } else { JointKind::Revolute };
            if j.kind != want_kind || (j.axis.into_inner() - expect_axis[k]).norm() > EXACT {
                return Err(err(format!(
                    "joint `{}`: analytic IK needs a {want_kind:?} joint about {:?}",
                    ARM_JOINTS[k], expect_axis[k]
                )));
            }
        }
        let origin = |k: usize| arm.joint(k).parent_from_joint;
        let straight = |k: usize| origin(k).rotation.angle() < EXACT;
        let flip = UnitQuaternion::from_euler_angles(PI, 0.0, 0.0);
        let (elbow, wrist, pitch, roll) = (origin(2), origin(3), origin(4), origin(5));
        let tcp = arm.link_poses(&[0.0; 6], 0.0)[arm.tcp_link];
        let gripper = arm.link_poses(&[0.0; 6], 0.0)[arm.joint(5).child];
        let gripper_from_tcp = gripper.inverse() * tcp;
        let checks = [
            (
                straight(0) && straight(1) && straight(2) && straight(3) && straight(5),
                "only the pitch joint may turn its frame",
            ),
            (
                elbow.translation.y.abs() < EXACT && wrist.translation.y.abs() < EXACT,
                "elbow and wrist yaw offsets must lie along x",
            ),
            (pitch.translation.vector.xy().norm() < EXACT, "the pitch axis must cross the yaw axis"),
            (pitch.rotation.angle_to(&flip) < EXACT, "the pitch joint must turn the tool to point down (rpy = pi 0 0)"),
            (roll.translation.vector.xy().norm() < EXACT, "the roll axis must pass through the wrist centre"),
            (
                gripper_from_tcp.translation.vector.xy().norm() < EXACT && gripper_from_tcp.rotation.angle() < EXACT,
                "the tcp must lie on the roll axis, unrotated",
            ),
        ];
        if let Some((_, why)) = checks.iter().find(|(ok, _)| !ok) {
            return Err(err(format!("analytic IK: {why}")));
        }
        let (zed, shoulder) = (origin(0).translation.vector, origin(1).translation.vector);
        Ok(Ik {
            shoulder_xy: (zed + shoulder).xy(),
            upper_arm: elbow.translation.x,
            forearm: wrist.translation.x,
            wrist_height_at_zero: zed.z + shoulder.z + elbow.translation.z + wrist.translation.z + pitch.translation.z,
            tool_length: roll.translation.z + gripper_from_tcp.translation.z,
            lower: arm.lower(),
            upper: arm.upper(),
        })
    }

    /// Every configuration within limits that puts the gripper at `base_from_gripper`.
    pub fn solve_all(&self, base_from_gripper: &Isometry3<f64>) -> Result<Vec<Joints>, IkError> {
        let rot = base_from_gripper.rotation.to_rotation_matrix();
        let approach = rot * Vector3::z();
        let wrist = base_from_gripper.translation.vector - self.tool_length * approach;
        let zed = wrist.z - self.wrist_height_at_zero;
        let arms = self.planar(&(wrist.xy() - self.shoulder_xy))?;
        let wrists = self.wrist_angles(&rot, &approach)?;
        let mut found = Vec::new();
        let mut first_violation = None;
        let arms = arms.iter().flat_map(|&(shoulder, elbow)| turns(shoulder).map(|s| (s, elbow)));
        for (shoulder, elbow) in arms {
            for &(psi, pitch, roll) in &wrists {
                let yaw = psi - shoulder - elbow;
                for yaw in turns(yaw) {
                    for roll in turns(roll) {
                        let q = [zed, shoulder, elbow, yaw, pitch, roll];
                        match self.violation(&q) {
                            None => found.push(q),
                            Some(e) => {
                                first_violation.get_or_insert(e);
                            }
                        }
                    }
                }
            }
        }
        if found.is_empty() { Err(first_violation.expect("candidates were tried")) } else { Ok(found) }
    }

    /// The solution nearest to `reference` (joint-space distance, zed weighted as [`WEIGHTS`]).
    pub fn solve_near(&self, base_from_gripper: &Isometry3<f64>, reference: &Joints) -> Result<Joints, IkError> {
        let all = self.solve_all(base_from_gripper)?;
        Ok(all.into_iter().min_by(|a, b| distance(a, reference).total_cmp(&distance(b, reference))).unwrap())
    }

    /// Shoulder and elbow angles that put the wrist centre at `xy` from the shoulder axis.
    fn planar(&self, xy: &Vector2<f64>) -> Result<Vec<(f64, f64)>, IkError> {
        let (l1, l2) = (self.upper_arm, self.forearm);
        let r2 = xy.norm_squared();
        let cos_elbow = (r2 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2);
        let elbow_max = self.upper[2].abs().max(self.lower[2].abs()).min(PI);
        let min_m = (l1 * l1 + l2 * l2 + 2.0 * l1 * l2 * elbow_max.cos()).max(0.0).sqrt();
        if !(-1.0..=1.0).contains(&cos_elbow) {
            return Err(IkError::OutOfReach { distance_m: r2.sqrt(), min_m, max_m: l1 + l2 });
        }
        let elbow = cos_elbow.acos();
        Ok([elbow, -elbow]
            .into_iter()
            .map(|e| (xy.y.atan2(xy.x) - (l2 * e.sin()).atan2(l1 + l2 * e.cos()), e))
            .collect())
    }

    /// (ψ, pitch, roll) triples giving `rot`.
    fn wrist_angles(&self, rot: &Rotation3<f64>, approach: &Vector3<f64>) -> Result<Vec<(f64, f64, f64)>, IkError> {
        let pitch = (-approach.z).clamp(-1.0, 1.0).acos();
        let limit = self.upper[4].min(-self.lower[4]);
        if pitch > limit + 1e-12 {
            return Err(IkError::TooTilted { tilt_deg: pitch.to_degrees(), limit_deg: limit.to_degrees() });
        }
        let flip = Rotation3::from_euler_angles(PI, 0.0, 0.0);
        let roll_of = |psi: f64, pitch: f64| {
            let n = Rotation3::from_euler_angles(0.0, pitch, 0.0).inverse()
                * flip.inverse()
                * Rotation3::from_euler_angles(0.0, 0.0, psi).inverse()
                * rot;
            n[(1, 0)].atan2(n[(0, 0)])
        };
        if pitch.sin().abs() < 1e-12 {
            // Straight down: only ψ - roll is fixed. Offer the split with roll 0 and the one
            // with ψ turned a quarter either way, so limits and the nearest-solution choice
            // have room.
            let m = rot * flip;
            let gamma = m[(1, 0)].atan2(m[(0, 0)]);
            return Ok([0.0, PI / 2.0, -PI / 2.0, PI].iter().map(|&d| (gamma + d, 0.0, d)).collect());
        }
        let psi = approach.y.atan2(approach.x);
        Ok(vec![(psi, pitch, roll_of(psi, pitch)), (psi + PI, -pitch, roll_of(psi + PI, -pitch))])
    }

    fn violation(&self, q: &Joints) -> Option<IkError> {
        (0..6).find(|&k| q[k] < self.lower[k] - 1e-12 || q[k] > self.upper[k] + 1e-12).map(|k| IkError::JointLimit {
            joint: ARM_JOINTS[k],
            value: q[k],
            lower: self.lower[k],
            upper: self.upper[k],
        })
    }
}

/// `angle` and its whole turns either way, wrapped first into (-π, π].
fn turns(angle: f64) -> [f64; 3] {
    let a = (angle + PI).rem_euclid(TAU) - PI;
    [a, a - TAU, a + TAU]
}

/// Joint-space weights: a metre of zed counts like 4 radians (the arm is about 0.5 m long).
pub const WEIGHTS: Joints = [4.0, 1.0, 1.0, 1.0, 1.0, 1.0];

/// Weighted Euclidean joint-space distance.
pub fn distance(a: &Joints, b: &Joints) -> f64 {
    (0..6).map(|k| (WEIGHTS[k] * (a[k] - b[k])).powi(2)).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::tests::umi;
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    fn ik() -> (Arm, Ik) {
        let arm = umi();
        let ik = Ik::new(&arm, "umi_rtx.urdf").unwrap();
        (arm, ik)
    }

    fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
        ((a.translation.vector - b.translation.vector).norm(), a.rotation.angle_to(&b.rotation))
    }

    #[test]
    fn fk_ik_round_trip_over_10000_random_reachable_poses() {
        let (arm, ik) = ik();
        let mut rng = StdRng::seed_from_u64(7);
        let (lo, hi) = (arm.lower(), arm.upper());
        let (mut worst_m, mut worst_rad, mut all_found) = (0.0f64, 0.0f64, 0);
        for _ in 0..10_000 {
            let q: Joints = std::array::from_fn(|k| rng.random_range(lo[k]..hi[k]));
            let target = arm.base_from_gripper(&q);
            let solutions = ik.solve_all(&target).unwrap_or_else(|e| panic!("{q:?}: {e}"));
            all_found += solutions.iter().any(|s| distance(s, &q) < 1e-6) as usize;
            for s in solutions {
                let (dm, dr) = pose_error(&arm.base_from_gripper(&s), &target);
                worst_m = worst_m.max(dm);
                worst_rad = worst_rad.max(dr);
            }
        }
        assert!(worst_m < 1e-6 && worst_rad < 1e-6, "worst {worst_m} m, {worst_rad} rad");
        // The configuration the pose came from is among the solutions (pitch 0 is measure zero).
        assert_eq!(all_found, 10_000);
    }

    #[test]
    fn both_elbow_solutions_are_offered() {
        let (arm, ik) = ik();
        let q = [0.4, 0.3, 1.0, -0.2, 0.3, 0.1];
        let sols = ik.solve_all(&arm.base_from_gripper(&q)).unwrap();
        assert!(sols.iter().any(|s| s[2] > 0.5) && sols.iter().any(|s| s[2] < -0.5), "{sols:?}");
    }

    #[test]
    fn straight_down_poses_are_solved() {
        let (arm, ik) = ik();
        let target = Isometry3::from_parts(
            nalgebra::Translation3::new(0.3, -0.1, 0.02),
            UnitQuaternion::from_euler_angles(PI, 0.0, 0.4),
        );
        let q = ik.solve_near(&target, &[0.3, 0.0, 0.0, 0.0, 0.0, 0.0]).unwrap();
        let (dm, dr) = pose_error(&arm.base_from_gripper(&q), &target);
        assert!(dm < 1e-9 && dr < 1e-9);
    }

    #[test]
    fn unreachable_poses_say_why() {
        let (_, ik) = ik();
        let down = UnitQuaternion::from_euler_angles(PI, 0.0, 0.0);
        let far = Isometry3::from_parts(nalgebra::Translation3::new(0.7, 0.0, 0.1), down);
        assert!(matches!(ik.solve_all(&far), Err(IkError::OutOfReach { .. })));
        let msg = ik.solve_all(&far).unwrap_err().to_string();
        assert!(msg.contains("0.700") && msg.contains("0.504"), "{msg}");
        let low = Isometry3::from_parts(nalgebra::Translation3::new(0.3, 0.0, -0.4), down);
        assert!(matches!(ik.solve_all(&low), Err(IkError::JointLimit { joint: "zed", .. })));
        let up = Isometry3::from_parts(nalgebra::Translation3::new(0.3, 0.0, 0.2), UnitQuaternion::identity());
        assert!(matches!(ik.solve_all(&up), Err(IkError::TooTilted { .. })));
    }
}
