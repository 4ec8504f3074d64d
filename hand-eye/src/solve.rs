//! The calibration routine: check the motion, start in closed form, refine on the flag's points,
//! drop outlier sightings one at a time (the worst, while it lies far beyond the others), and
//! report the transforms, their covariance and the residuals.

use crate::motion::{self, MotionError};
use crate::refine::{PARAMS, PointProblem, minimise, sigmas};
pub use crate::sighting::Sighting;
use nalgebra::{Isometry3, Point3, SMatrix};

/// The routine's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct SolveParams {
    /// Points of the flag (its frame) whose residuals are minimised: the plate's corners.
    pub flag_points: Vec<Point3<f64>>,
    /// A sighting is an outlier when its RMS point residual exceeds this many times the median
    /// sighting's...
    pub outlier_factor: f64,
    /// ...and this much (metres): below it, nothing is an outlier.
    pub outlier_floor_m: f64,
    /// At most this fraction of the sightings is dropped.
    pub max_dropped_fraction: f64,
    /// A sighting whose flag turns, against the others', by angles this far (median, radians)
    /// from those the robot turned its gripper is dropped before the solve.
    pub max_angle_disagreement_rad: f64,
}

impl SolveParams {
    /// For a box-shaped flag of these half extents (metres): its 8 corners.
    pub fn for_box(half: [f64; 3]) -> SolveParams {
        let [a, b, c] = half;
        let flag_points = [-1.0, 1.0]
            .iter()
            .flat_map(|&x| {
                [-1.0, 1.0].into_iter().flat_map(move |y| [-1.0, 1.0].map(|z| Point3::new(x * a, y * b, z * c)))
            })
            .collect();
        SolveParams {
            flag_points,
            outlier_factor: 4.0,
            outlier_floor_m: 0.5e-3,
            max_dropped_fraction: 0.34,
            max_angle_disagreement_rad: 2f64.to_radians(),
        }
    }
}

/// Why there is no solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HandEyeError {
    #[error(transparent)]
    Motion(#[from] MotionError),
    #[error("the least-squares problem is singular: {0}")]
    Singular(String),
}

/// The result.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    pub cam_from_base: Isometry3<f64>,
    pub gripper_from_flag: Isometry3<f64>,
    /// Covariance of the 12 parameters: rotation vector (rad) and translation (m) of
    /// `cam_from_base` (the rotation applied on the left), then of `gripper_from_flag`.
    pub covariance: SMatrix<f64, PARAMS, PARAMS>,
    /// Standard deviations, the largest axis of each block: `cam_from_base` rotation (deg) and
    /// translation (mm), `gripper_from_flag` rotation (deg) and translation (mm).
    pub sigma: Sigmas,
    /// RMS over the sightings used of the flag points' distance from where the solution puts
    /// them (mm), and of the angle between the flag's measured and predicted rotations (deg).
    pub residual_mm_rms: f64,
    pub residual_deg_rms: f64,
    /// For each sighting, whether it was used.
    pub used: Vec<bool>,
    /// The sightings dropped as outliers, with why.
    pub dropped: Vec<(usize, String)>,
}

/// Standard deviations of the solution (largest axis of each block).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sigmas {
    pub cam_from_base_deg: f64,
    pub cam_from_base_mm: f64,
    pub gripper_from_flag_deg: f64,
    pub gripper_from_flag_mm: f64,
}

/// Solves `cam_from_base` and `gripper_from_flag` from the sightings.
pub fn solve(sightings: &[Sighting], params: &SolveParams) -> Result<Solution, HandEyeError> {
    let all: Vec<(Isometry3<f64>, Isometry3<f64>)> =
        sightings.iter().map(|s| (s.base_from_gripper, s.cam_from_flag)).collect();
    let mut used = vec![true; all.len()];
    let mut dropped = Vec::new();
    // Readings that disagree with the rest on how far the flag turned go first: they would
    // spoil the closed-form start, which the point residuals' outlier test then trusts.
    for (i, d) in crate::symmetry::disagreement(sightings).into_iter().enumerate() {
        if d > params.max_angle_disagreement_rad {
            used[i] = false;
            dropped.push((
                i,
                format!(
                    "sighting {i}: the flag turned by angles {:.1} deg (median) off those the gripper turned",
                    d.to_degrees()
                ),
            ));
        }
    }
    let max_dropped = (params.max_dropped_fraction * all.len() as f64).floor() as usize;
    let mut start: Option<(Isometry3<f64>, Isometry3<f64>)> = None;
    loop {
        let kept: Vec<(Isometry3<f64>, Isometry3<f64>)> =
            all.iter().zip(&used).filter(|(_, u)| **u).map(|(s, _)| *s).collect();
        motion::check(&kept.iter().map(|s| s.0).collect::<Vec<_>>())?;
        let first = match start {
            Some(s) => s,
            None => {
                crate::closed_form::solve(&kept).ok_or_else(|| HandEyeError::Singular("no closed-form start".into()))?
            }
        };
        let (solved, _) = minimise(PointProblem::new(&kept, &params.flag_points, first));
        let (x, y) = solved.transforms();
        let rms: Vec<f64> = all.iter().map(|s| point_rms(s, &x, &y, &params.flag_points)).collect();
        let mut used_rms: Vec<f64> = rms.iter().zip(&used).filter(|(_, u)| **u).map(|(r, _)| *r).collect();
        used_rms.sort_by(f64::total_cmp);
        let median = used_rms[used_rms.len() / 2];
        let worst = (0..all.len()).filter(|&i| used[i]).max_by(|&a, &b| rms[a].total_cmp(&rms[b])).expect("some used");
        let limit = (params.outlier_factor * median).max(params.outlier_floor_m);
        if rms[worst] > limit && dropped.len() < max_dropped {
            used[worst] = false;
            dropped.push((
                worst,
                format!(
                    "sighting {worst}: its flag points lie {:.2} mm (RMS) from where the others put them; the median sighting's {:.2} mm",
                    rms[worst] * 1e3,
                    median * 1e3
                ),
            ));
            start = Some((x, y));
            continue;
        }
        let covariance =
            solved.covariance().ok_or_else(|| HandEyeError::Singular("J^T J cannot be inverted".into()))?;
        let [rx, tx, ry, ty] = sigmas(&covariance);
        let n = used_rms.len() as f64;
        let residual_mm_rms = (used_rms.iter().map(|r| r * r).sum::<f64>() / n).sqrt() * 1e3;
        let angles: Vec<f64> = kept.iter().map(|(b, c)| (x * b * y).rotation.angle_to(&c.rotation)).collect();
        let residual_deg_rms = (angles.iter().map(|a| a * a).sum::<f64>() / n).sqrt().to_degrees();
        return Ok(Solution {
            cam_from_base: x,
            gripper_from_flag: y,
            covariance,
            sigma: Sigmas {
                cam_from_base_deg: rx.to_degrees(),
                cam_from_base_mm: tx * 1e3,
                gripper_from_flag_deg: ry.to_degrees(),
                gripper_from_flag_mm: ty * 1e3,
            },
            residual_mm_rms,
            residual_deg_rms,
            used,
            dropped,
        });
    }
}

/// RMS distance of the flag's points between where vision saw them and where the solution puts
/// them, one sighting.
fn point_rms(
    s: &(Isometry3<f64>, Isometry3<f64>),
    x: &Isometry3<f64>,
    y: &Isometry3<f64>,
    points: &[Point3<f64>],
) -> f64 {
    let predicted = x * s.0 * y;
    let sum: f64 = points.iter().map(|p| (s.1 * p - predicted * p).norm_squared()).sum();
    (sum / points.len().max(1) as f64).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::{log, pose_error};
    use nalgebra::{Matrix3, Translation3, UnitQuaternion, Vector3};
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};
    use rand_distr::{Distribution, Normal};

    fn params() -> SolveParams {
        SolveParams::for_box([0.03, 0.02, 0.002])
    }

    fn synthetic_transforms() -> (Isometry3<f64>, Isometry3<f64>) {
        let x = Isometry3::from_parts(
            Translation3::new(-0.04, -0.18, 1.12),
            UnitQuaternion::from_euler_angles(2.1, -0.6, 0.9),
        );
        let y = Isometry3::from_parts(
            Translation3::new(0.0, 0.0, 0.022),
            UnitQuaternion::from_euler_angles(-std::f64::consts::FRAC_PI_2, 0.0, -std::f64::consts::FRAC_PI_2),
        );
        (x, y)
    }

    /// Gripper poses over a workspace, with pitch and roll; flag sightings from these transforms with
    /// Gaussian pose noise (rotation sigma `sr` rad about a random axis, translation `st` m).
    fn sightings(n: usize, sr: f64, st: f64, seed: u64) -> Vec<Sighting> {
        let (x, y) = synthetic_transforms();
        let mut rng = StdRng::seed_from_u64(seed);
        let (nr, nt) = (Normal::new(0.0, sr.max(1e-300)).unwrap(), Normal::new(0.0, st.max(1e-300)).unwrap());
        (0..n)
            .map(|_| {
                let t = Translation3::new(
                    rng.random_range(0.2..0.45),
                    rng.random_range(-0.25..0.25),
                    rng.random_range(0.1..0.4),
                );
                let r = UnitQuaternion::from_euler_angles(
                    std::f64::consts::PI + rng.random_range(-0.5..0.5),
                    rng.random_range(-0.6..0.6),
                    rng.random_range(-3.0..3.0),
                );
                let b = Isometry3::from_parts(t, r);
                let w = Vector3::new(nr.sample(&mut rng), nr.sample(&mut rng), nr.sample(&mut rng));
                let dt = Vector3::new(nt.sample(&mut rng), nt.sample(&mut rng), nt.sample(&mut rng));
                let c = x * b * y;
                let noisy = Isometry3::from_parts(
                    Translation3::from(c.translation.vector + dt),
                    UnitQuaternion::from_scaled_axis(w) * c.rotation,
                );
                Sighting { base_from_gripper: b, cam_from_flag: noisy }
            })
            .collect()
    }

    #[test]
    fn exact_sightings_give_the_transforms_to_1e_9() {
        let (x, y) = synthetic_transforms();
        let s = solve(&sightings(12, 0.0, 0.0, 1), &params()).unwrap();
        let (dt, dr) = pose_error(&s.cam_from_base, &x);
        assert!(dt < 1e-9 && dr < 1e-9, "cam_from_base off by {dt} m, {dr} rad");
        let (dt, dr) = pose_error(&s.gripper_from_flag, &y);
        assert!(dt < 1e-9 && dr < 1e-9, "gripper_from_flag off by {dt} m, {dr} rad");
        assert!(s.residual_mm_rms < 1e-6 && s.dropped.is_empty());
    }

    /// The error of an estimate against the synthetic transforms as the covariance measures it: left
    /// rotation vector and translation difference, six numbers.
    fn error_vector(x: &Isometry3<f64>, exact: &Isometry3<f64>) -> [f64; 6] {
        let w = log(&(exact.rotation * x.rotation.inverse()));
        let t = exact.translation.vector - x.translation.vector;
        [w.x, w.y, w.z, t.x, t.y, t.z]
    }

    /// The error of `cam_from_base` against the synthetic one, in units of the reported covariance: its
    /// squared Mahalanobis length, rotation and translation apart.
    fn mahalanobis(s: &Solution) -> (f64, f64) {
        let e = error_vector(&s.cam_from_base, &synthetic_transforms().0);
        let block = |k: usize| {
            let cov: Matrix3<f64> = s.covariance.fixed_view::<3, 3>(k, k).into_owned();
            let v = Vector3::new(e[k], e[k + 1], e[k + 2]);
            (v.transpose() * cov.try_inverse().unwrap() * v)[0]
        };
        (block(0), block(3))
    }

    /// Noisy sightings: the error lies within 3 sigma of the reported covariance. For three
    /// degrees of freedom that is a squared Mahalanobis length under 14.2 (99.7%); over 20 seeded
    /// calibrations at most one may exceed it (the chance of two or more is under 2%).
    #[test]
    fn noisy_sightings_give_an_error_within_3_sigma_of_the_covariance() {
        let mut beyond = 0;
        for seed in 0..20 {
            let s = solve(&sightings(20, 0.004, 0.3e-3, 100 + seed), &params()).unwrap();
            let (rot, trans) = mahalanobis(&s);
            beyond += (rot > 14.2) as usize + (trans > 14.2) as usize;
            assert!(s.sigma.cam_from_base_mm > 0.01 && s.sigma.cam_from_base_mm < 1.0, "{:?}", s.sigma);
        }
        assert!(beyond <= 1, "{beyond} of 40 blocks beyond 3 sigma");
    }

    #[test]
    fn gross_outliers_are_dropped_and_the_result_stays_within_the_noise() {
        let mut s = sightings(20, 0.004, 0.3e-3, 7);
        let clean = solve(&s, &params()).unwrap();
        assert!(clean.dropped.is_empty(), "{:?}", clean.dropped);
        // 20%: four sightings read 1-3 cm and 3-10 deg wrong (a flag mistaken for something else).
        let bad = [2, 7, 11, 16];
        for (k, &i) in bad.iter().enumerate() {
            let wrong = Isometry3::from_parts(
                Translation3::new(0.01 * (k + 1) as f64, -0.015, 0.02),
                UnitQuaternion::from_euler_angles(0.05 * (k + 1) as f64, 0.1, 0.0),
            );
            s[i].cam_from_flag = wrong * s[i].cam_from_flag;
        }
        let got = solve(&s, &params()).unwrap();
        let mut dropped: Vec<usize> = got.dropped.iter().map(|(i, _)| *i).collect();
        dropped.sort();
        assert_eq!(dropped, bad, "{:?}", got.dropped);
        assert!(got.dropped.iter().all(|(i, why)| why.starts_with(&format!("sighting {i}:"))), "{:?}", got.dropped);
        let (dt, dr) = pose_error(&got.cam_from_base, &synthetic_transforms().0);
        let (ct, cr) = pose_error(&clean.cam_from_base, &synthetic_transforms().0);
        // Within the noise: no worse than 3 sigma, and near what the clean sightings give.
        assert!(
            dt * 1e3 < 3.0 * got.sigma.cam_from_base_mm && dr.to_degrees() < 3.0 * got.sigma.cam_from_base_deg,
            "{dt} m, {dr} rad"
        );
        assert!((dt - ct).abs() < 0.5e-3 && (dr - cr).abs() < 0.002, "clean {ct} {cr}, with outliers {dt} {dr}");
    }

    #[test]
    fn degenerate_motion_is_refused_with_its_reason() {
        let mut s = sightings(8, 0.0, 0.0, 3);
        // Only the SCARA's vertical axes: no pitch, no roll.
        let (x, y) = synthetic_transforms();
        for (k, si) in s.iter_mut().enumerate() {
            let b = Isometry3::from_parts(
                si.base_from_gripper.translation,
                UnitQuaternion::from_euler_angles(std::f64::consts::PI, 0.0, 0.4 * k as f64),
            );
            *si = Sighting { base_from_gripper: b, cam_from_flag: x * b * y };
        }
        let e = solve(&s, &params()).unwrap_err();
        assert!(matches!(e, HandEyeError::Motion(MotionError::OneAxis { .. })), "{e}");
        assert!(e.to_string().contains("pitch or roll"), "{e}");
        let e = solve(&sightings(2, 0.0, 0.0, 3), &params()).unwrap_err();
        assert!(e.to_string().contains("too few"), "{e}");
    }
}
