//! A symmetric flag is seen only up to its symmetry: a rectangular plate turned half a turn
//! looks the same, so vision may report any of its equivalent poses, and not the same one in
//! every sighting. Before the solve, each sighting's reading is chosen among its equivalents so
//! that all agree: between two sightings the camera must see the flag turn by the same angle as
//! the robot turned its gripper (`A = X B X^-1` keeps the rotation angle), whatever `X` is.

use crate::sighting::Sighting;
use nalgebra::Isometry3;

/// Most one earlier sighting's disagreement can weigh (radians).
const MAX_SAY_RAD: f64 = 5.0 * std::f64::consts::PI / 180.0;

/// How far each sighting's rotation angles disagree with the others' (radians, the median over
/// them): between two sightings the camera must see the flag turn by the angle the robot turned
/// its gripper. A sighting far off the rest read the flag wrongly.
pub fn disagreement(sightings: &[Sighting]) -> Vec<f64> {
    sightings
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let mut d: Vec<f64> = sightings
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, o)| {
                    let seen = (s.cam_from_flag.rotation * o.cam_from_flag.rotation.inverse()).angle();
                    let moved = (s.base_from_gripper.rotation * o.base_from_gripper.rotation.inverse()).angle();
                    (seen - moved).abs()
                })
                .collect();
            d.sort_by(f64::total_cmp);
            d.get(d.len() / 2).copied().unwrap_or(0.0)
        })
        .collect()
}

/// The sightings with each `cam_from_flag` replaced by the equivalent reading (`C S`, `S` one of
/// `symmetries`, the flag's own symmetries in its frame) that agrees best with the others.
/// The first sighting's reading is kept as read; the rest are chosen one by one, each against
/// all those already chosen.
pub fn resolve(sightings: &[Sighting], symmetries: &[Isometry3<f64>]) -> Vec<Sighting> {
    let mut out: Vec<Sighting> = Vec::with_capacity(sightings.len());
    for s in sightings {
        // Each earlier sighting's say is capped, so that a wrong one cannot outvote the rest.
        let disagreement = |c: &Isometry3<f64>| -> f64 {
            out.iter()
                .map(|o| {
                    let seen = (c.rotation * o.cam_from_flag.rotation.inverse()).angle();
                    let moved = (s.base_from_gripper.rotation * o.base_from_gripper.rotation.inverse()).angle();
                    (seen - moved).abs().min(MAX_SAY_RAD)
                })
                .sum()
        };
        let best = symmetries
            .iter()
            .map(|g| s.cam_from_flag * g)
            .min_by(|a, b| disagreement(a).total_cmp(&disagreement(b)))
            .unwrap_or(s.cam_from_flag);
        out.push(Sighting { base_from_gripper: s.base_from_gripper, cam_from_flag: best });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    #[test]
    fn flipped_readings_are_brought_into_agreement() {
        let x = Isometry3::from_parts(
            Translation3::new(-0.04, -0.18, 1.12),
            UnitQuaternion::from_euler_angles(2.1, -0.6, 0.9),
        );
        let y = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.05),
            UnitQuaternion::from_euler_angles(-1.2, 0.1, -1.4),
        );
        let half = |axis: Vector3<f64>| Isometry3::rotation(axis * std::f64::consts::PI);
        let symmetries = [Isometry3::identity(), half(Vector3::x()), half(Vector3::y()), half(Vector3::z())];
        let sightings: Vec<Sighting> = (0..10)
            .map(|k| {
                let k = k as f64;
                let b = Isometry3::from_parts(
                    Translation3::new(0.3 + 0.01 * k, 0.02 * k - 0.1, 0.2),
                    UnitQuaternion::from_euler_angles(3.0 + 0.05 * k, 0.3 * (k * 1.7).sin(), 0.4 * k),
                );
                // Every reading flipped by one of the symmetries, in turn.
                let flip = symmetries[(k as usize * 7) % 4];
                Sighting { base_from_gripper: b, cam_from_flag: x * b * y * flip }
            })
            .collect();
        let resolved = resolve(&sightings, &symmetries);
        // All now read the flag alike: the same flip as the first one's (identity here).
        for s in &resolved {
            let c = x * s.base_from_gripper * y;
            assert!((s.cam_from_flag.translation.vector - c.translation.vector).norm() < 1e-9);
            assert!(s.cam_from_flag.rotation.angle_to(&c.rotation) < 1e-9);
        }
    }
}
