//! The whole calibration of a stereo pair from board detections: for each camera its checks
//! ([`crate::checks`]), Zhang's start ([`crate::zhang`]) and its own adjustment; the right
//! camera's pose in the left's from the views both saw; then one joint adjustment of both
//! cameras, the rig and every board pose ([`crate::adjust`]), with per-view reprojection RMS
//! and the parameters' standard deviations.

use crate::adjust::{self, Observation, Problem, State};
use crate::board::Board;
use crate::camera::{INTRINSICS, Intrinsics};
use crate::checks::{self, Degenerate};
use crate::zhang;
use nalgebra::{DMatrix, Isometry3, Point2, Quaternion, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// One view: the corners each camera found (the whole board, in [`Board::points`]'s order),
/// or `None` where it did not.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ViewCorners {
    pub left: Option<Vec<Point2<f64>>>,
    pub right: Option<Vec<Point2<f64>>>,
}

impl ViewCorners {
    fn of(&self, camera: usize) -> Option<&Vec<Point2<f64>>> {
        if camera == 0 { self.left.as_ref() } else { self.right.as_ref() }
    }
}

/// How the solve runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Options {
    /// Solve for k3 too (otherwise it stays 0, as OpenCV's default for narrow lenses).
    pub solve_k3: bool,
    /// Rounds of Huber reweighting in the joint adjustment.
    pub robust_rounds: usize,
    /// The Huber threshold's floor, pixels.
    pub huber_floor_px: f64,
}

impl Default for Options {
    fn default() -> Self {
        Options { solve_k3: false, robust_rounds: 3, huber_floor_px: 0.1 }
    }
}

/// What went wrong, beyond a degenerate set.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    #[error(transparent)]
    Degenerate(#[from] Degenerate),
    #[error("no view was seen by both cameras, so their relative pose is unknown")]
    NoCommonView,
    #[error("the adjustment did not converge")]
    NoConvergence,
    #[error("the solution's covariance is singular: some parameter is not determined by these views")]
    Singular,
}

/// A view's reprojection RMS in each camera (pixels; `None` where the camera did not see it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViewFit {
    pub left_rms_px: Option<f64>,
    pub right_rms_px: Option<f64>,
}

/// The calibrated pair.
#[derive(Debug, Clone, PartialEq)]
pub struct StereoSolution {
    pub left: Intrinsics,
    pub right: Intrinsics,
    pub right_from_left: Isometry3<f64>,
    /// Each view's `left_from_board` (`None` for views neither camera saw).
    pub boards: Vec<Option<Isometry3<f64>>>,
    /// Standard deviations of the left and right intrinsics (in [`Intrinsics::to_params`]'s
    /// order) and of `right_from_left` (rotation vector, radians; translation, metres).
    pub left_sigma: [f64; INTRINSICS],
    pub right_sigma: [f64; INTRINSICS],
    pub rig_sigma: [f64; 6],
    /// The covariance of `[left intrinsics, right intrinsics, right_from_left]` (24 x 24).
    pub covariance: DMatrix<f64>,
    pub views: Vec<ViewFit>,
    /// Reprojection RMS over every corner of the joint adjustment, pixels.
    pub rms_px: f64,
    pub left_rms_px: f64,
    pub right_rms_px: f64,
}

/// Each view's board pose in a camera, `None` where the camera did not see the board.
pub type BoardPoses = Vec<Option<Isometry3<f64>>>;

const NAMES: [&str; 2] = ["left", "right"];

/// Calibrates a stereo pair of `size` pixels from the views' corners.
pub fn calibrate_stereo(
    board: &Board,
    size: [u32; 2],
    views: &[ViewCorners],
    options: &Options,
) -> Result<StereoSolution, CalibrationError> {
    let points = board.points();
    let mut cameras = Vec::new();
    let mut poses: Vec<BoardPoses> = Vec::new();
    for camera in 0..2 {
        let (intrinsics, cam_poses) = calibrate_one(board, size, views, camera, options)?;
        cameras.push(intrinsics);
        poses.push(cam_poses);
    }
    let rig = rig_start(&poses[0], &poses[1]).ok_or(CalibrationError::NoCommonView)?;
    // Each view's left_from_board: the left camera's, or from the right's through the rig.
    let seen: Vec<usize> = (0..views.len()).filter(|&v| poses[0][v].is_some() || poses[1][v].is_some()).collect();
    let boards: Vec<Isometry3<f64>> =
        seen.iter().map(|&v| poses[0][v].unwrap_or_else(|| rig.inverse() * poses[1][v].expect("seen"))).collect();
    let observations = observations_of(views, &seen, &[0, 1]);
    let state = State { cameras, rig: Some(rig), views: boards };
    let problem = Problem::new(&observations, &points, state, options.solve_k3);
    let (solved, _) = adjust::minimise(problem, options.robust_rounds, options.huber_floor_px);
    let covariance = solved.covariance().ok_or(CalibrationError::Singular)?;
    Ok(summarise(&solved, &covariance, views.len(), &seen))
}

/// The corners of `views` (those listed in `seen`, renumbered in that order) by `cameras`.
fn observations_of(views: &[ViewCorners], seen: &[usize], cameras: &[usize]) -> Vec<Observation> {
    let mut out = Vec::new();
    for (k, &v) in seen.iter().enumerate() {
        for &camera in cameras {
            if let Some(corners) = views[v].of(camera) {
                out.extend(corners.iter().enumerate().map(|(corner, &pixel)| Observation {
                    camera: if cameras.len() == 1 { 0 } else { camera },
                    view: k,
                    corner,
                    pixel,
                }));
            }
        }
    }
    out
}

/// One camera on its own: checks, Zhang's start, its adjustment. Its intrinsics and each view's
/// `cam_from_board` (`None` where it did not see the board).
pub fn calibrate_one(
    board: &Board,
    size: [u32; 2],
    views: &[ViewCorners],
    camera: usize,
    options: &Options,
) -> Result<(Intrinsics, BoardPoses), CalibrationError> {
    let name = NAMES[camera];
    let seen: Vec<usize> = (0..views.len()).filter(|&v| views[v].of(camera).is_some()).collect();
    if seen.len() < checks::MIN_VIEWS {
        return Err(Degenerate::TooFewViews { camera: name, views: seen.len() }.into());
    }
    let fraction =
        checks::coverage(seen.iter().flat_map(|&v| views[v].of(camera).expect("seen").iter().copied()), size);
    if fraction < checks::MIN_COVERAGE {
        return Err(Degenerate::PoorCoverage { camera: name, fraction }.into());
    }
    let plane: Vec<Point2<f64>> = board.points().iter().map(|p| Point2::new(p.x, p.y)).collect();
    let homographies: Vec<_> =
        seen.iter().filter_map(|&v| zhang::homography(&plane, views[v].of(camera).expect("seen"))).collect();
    let start = zhang::intrinsics(&homographies)
        .filter(|k| k.fx.is_finite() && k.fy.is_finite())
        .ok_or(Degenerate::NoClosedForm { camera: name })?;
    let starts: Vec<Isometry3<f64>> = homographies
        .iter()
        .map(|h| zhang::board_pose(h, &start.k()).ok_or(Degenerate::NoClosedForm { camera: name }))
        .collect::<Result<_, _>>()?;
    let largest_tilt_deg = starts.iter().map(checks::tilt_deg).fold(0.0, f64::max);
    if largest_tilt_deg < checks::MIN_LARGEST_TILT_DEG {
        return Err(Degenerate::FrontoParallel { camera: name, largest_tilt_deg }.into());
    }
    let points = board.points();
    let observations = observations_of(views, &seen, &[camera]);
    let state = State { cameras: vec![start], rig: None, views: starts };
    let (solved, _) =
        adjust::minimise(Problem::new(&observations, &points, state, options.solve_k3), 2, options.huber_floor_px);
    let mut poses = vec![None; views.len()];
    for (k, &v) in seen.iter().enumerate() {
        poses[v] = Some(solved.state.views[k]);
    }
    Ok((solved.state.cameras[0], poses))
}

/// The right camera's pose in the left's from the views both saw: the mean rotation (of the
/// quaternions, made to agree in sign) and the mean translation.
fn rig_start(left: &[Option<Isometry3<f64>>], right: &[Option<Isometry3<f64>>]) -> Option<Isometry3<f64>> {
    let each: Vec<Isometry3<f64>> =
        left.iter().zip(right).filter_map(|(l, r)| Some(r.as_ref()? * l.as_ref()?.inverse())).collect();
    let first = each.first()?;
    let n = each.len() as f64;
    let q = each.iter().fold(Vector3::zeros().push(0.0), |sum, e| {
        let c = e.rotation.coords;
        sum + if c.dot(&first.rotation.coords) < 0.0 { -c } else { c }
    });
    let t = each.iter().fold(Vector3::zeros(), |sum, e| sum + e.translation.vector) / n;
    Some(Isometry3::from_parts(t.into(), UnitQuaternion::from_quaternion(Quaternion::from(q))))
}

fn summarise(solved: &Problem<'_>, covariance: &DMatrix<f64>, view_count: usize, seen: &[usize]) -> StereoSolution {
    let s = &solved.state;
    let sigma = |i: usize| covariance[(i, i)].max(0.0).sqrt();
    let block = |start: usize| -> [f64; INTRINSICS] { std::array::from_fn(|k| sigma(start + k)) };
    let errors = solved.errors();
    let rms = |filter: &dyn Fn(&Observation) -> bool| {
        let (sum, n) = solved
            .observations
            .iter()
            .zip(&errors)
            .filter(|(o, _)| filter(o))
            .fold((0.0, 0usize), |(s, n), (_, e)| (s + e.norm_squared(), n + 1));
        (n > 0).then(|| (sum / n as f64).sqrt())
    };
    let mut boards = vec![None; view_count];
    let mut views = vec![ViewFit { left_rms_px: None, right_rms_px: None }; view_count];
    for (k, &v) in seen.iter().enumerate() {
        boards[v] = Some(s.views[k]);
        views[v] = ViewFit {
            left_rms_px: rms(&|o| o.view == k && o.camera == 0),
            right_rms_px: rms(&|o| o.view == k && o.camera == 1),
        };
    }
    let r = 2 * INTRINSICS;
    StereoSolution {
        left: s.cameras[0],
        right: s.cameras[1],
        right_from_left: s.rig.expect("a stereo state"),
        boards,
        left_sigma: block(0),
        right_sigma: block(INTRINSICS),
        rig_sigma: std::array::from_fn(|k| sigma(r + k)),
        covariance: covariance.view((0, 0), (r + 6, r + 6)).into_owned(),
        views,
        rms_px: rms(&|_| true).unwrap_or(0.0),
        left_rms_px: rms(&|o| o.camera == 0).unwrap_or(0.0),
        right_rms_px: rms(&|o| o.camera == 1).unwrap_or(0.0),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use mesh::distortion::PlumbBob;
    use nalgebra::Translation3;
    use rand::{SeedableRng, rngs::StdRng};
    use rand_distr::{Distribution, Normal};

    pub const SIZE: [u32; 2] = [512, 512];

    /// A rig like the cell's: 1000 px lenses with barrel distortion, 0.25 m apart, verged 8 deg
    /// on a point 0.75 m out.
    pub fn rig() -> (Intrinsics, Intrinsics, Isometry3<f64>) {
        let left = Intrinsics {
            distortion: PlumbBob::from_d([-0.2, 0.09, 3e-4, -2e-4, 0.0]),
            ..Intrinsics::pinhole(1002.0, 998.0, 253.0, 259.0)
        };
        let right = Intrinsics {
            distortion: PlumbBob::from_d([-0.19, 0.08, -2e-4, 3e-4, 0.0]),
            ..Intrinsics::pinhole(996.0, 1001.0, 258.0, 252.0)
        };
        let right_from_left = Isometry3::from_parts(
            Translation3::new(-0.234, 0.003, 0.080),
            UnitQuaternion::from_euler_angles(0.004, 0.33, 0.002),
        );
        (left, right, right_from_left)
    }

    /// Board poses (`left_from_board`) over the pair's common view: a 4 x 3 grid of places,
    /// each board tilted 20-40 deg in its own direction.
    pub fn boards() -> Vec<Isometry3<f64>> {
        let board = Board::LIBRARY;
        let centre = Vector3::new(4.0 * board.square_m, 2.5 * board.square_m, 0.0);
        let mut out = Vec::new();
        for j in 0..3 {
            for i in 0..4 {
                let k = (j * 4 + i) as f64;
                let place = Vector3::new(-0.075 + 0.055 * i as f64, -0.085 + 0.085 * j as f64, 0.72 + 0.02 * (k % 3.0));
                let tilt = (20.0 + 20.0 * ((k * 0.37) % 1.0)).to_radians();
                let direction = k * 2.4;
                let axis = nalgebra::Unit::new_normalize(Vector3::new(direction.cos(), direction.sin(), 0.0));
                let rotation = UnitQuaternion::from_axis_angle(&axis, tilt)
                    * UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3 * (k % 2.0 - 0.5));
                // Place the board's centre, not its first corner.
                let t = place - rotation * centre;
                out.push(Isometry3::from_parts(t.into(), rotation));
            }
        }
        out
    }

    /// The views of `boards` by the rig, with Gaussian noise of `sigma_px` on every corner.
    pub fn views(boards: &[Isometry3<f64>], sigma_px: f64, seed: u64) -> Vec<ViewCorners> {
        let (left, right, right_from_left) = rig();
        let mut rng = StdRng::seed_from_u64(seed);
        let noise = Normal::new(0.0, sigma_px.max(1e-300)).unwrap();
        let mut image = |cam: &Intrinsics, pose: &Isometry3<f64>| -> Option<Vec<Point2<f64>>> {
            let pts: Option<Vec<Point2<f64>>> =
                Board::LIBRARY.points().iter().map(|p| cam.project(&(pose * p))).collect();
            let pts = pts?;
            let inside =
                pts.iter().all(|p| (0.0..SIZE[0] as f64).contains(&p.x) && (0.0..SIZE[1] as f64).contains(&p.y));
            inside.then(|| {
                pts.iter()
                    .map(|p| {
                        if sigma_px > 0.0 {
                            Point2::new(p.x + noise.sample(&mut rng), p.y + noise.sample(&mut rng))
                        } else {
                            *p
                        }
                    })
                    .collect()
            })
        };
        boards
            .iter()
            .map(|b| ViewCorners { left: image(&left, b), right: image(&right, &(right_from_left * b)) })
            .collect()
    }

    #[test]
    fn the_synthetic_views_are_seen_by_both_cameras() {
        let v = views(&boards(), 0.0, 1);
        let both = v.iter().filter(|v| v.left.is_some() && v.right.is_some()).count();
        assert!(both >= 10, "{both} of {} views seen by both cameras", v.len());
    }

    #[test]
    fn exact_views_are_solved_to_1e_9() {
        let (left, right, right_from_left) = rig();
        let s = calibrate_stereo(&Board::LIBRARY, SIZE, &views(&boards(), 0.0, 1), &Options::default()).unwrap();
        for (got, want) in [(s.left, left), (s.right, right)] {
            for (k, (a, b)) in got.to_params().iter().zip(want.to_params()).enumerate() {
                let scale = if k < 4 { 1e3 } else { 1.0 };
                assert!((a - b).abs() <= 1e-9 * scale, "param {k}: {a} vs {b}");
            }
        }
        assert!((s.right_from_left.translation.vector - right_from_left.translation.vector).norm() < 1e-9);
        assert!(s.right_from_left.rotation.angle_to(&right_from_left.rotation) < 1e-9);
        assert!(s.rms_px < 1e-9, "rms {}", s.rms_px);
    }

    #[test]
    fn too_few_views_are_refused() {
        let v = views(&boards()[..5], 0.0, 1);
        let e = calibrate_stereo(&Board::LIBRARY, SIZE, &v, &Options::default()).unwrap_err();
        assert!(matches!(e, CalibrationError::Degenerate(Degenerate::TooFewViews { views: 5, .. })), "{e}");
    }

    #[test]
    fn corners_in_one_part_of_the_image_are_refused() {
        // Every board in the same place, tilted differently: the corners cover a patch.
        let all = boards();
        let mut crowded: Vec<Isometry3<f64>> = Vec::new();
        for b in &all {
            let mut c = *b;
            c.translation.vector += all[5].translation.vector - b.translation.vector;
            crowded.push(c);
        }
        let e = calibrate_stereo(&Board::LIBRARY, SIZE, &views(&crowded, 0.0, 1), &Options::default()).unwrap_err();
        assert!(matches!(e, CalibrationError::Degenerate(Degenerate::PoorCoverage { .. })), "{e}");
        assert!(e.to_string().contains("cover"), "{e}");
    }

    #[test]
    fn fronto_parallel_boards_are_refused() {
        let board = Board::LIBRARY;
        let centre = Vector3::new(4.0 * board.square_m, 2.5 * board.square_m, 0.0);
        let flat: Vec<Isometry3<f64>> = (0..12)
            .map(|k| {
                let (i, j) = ((k % 4) as f64, (k / 4) as f64);
                let r =
                    UnitQuaternion::from_euler_angles(0.02 * (k % 3) as f64, -0.03 * (k % 2) as f64, 0.1 * k as f64);
                let place = Vector3::new(-0.12 + 0.08 * i + 0.06, -0.09 + 0.09 * j, 0.75);
                Isometry3::from_parts((place - r * centre).into(), r)
            })
            .collect();
        let v = views(&flat, 0.05, 3);
        let e = calibrate_stereo(&board, SIZE, &v, &Options::default()).unwrap_err();
        assert!(
            matches!(
                e,
                CalibrationError::Degenerate(Degenerate::FrontoParallel { .. } | Degenerate::NoClosedForm { .. })
            ),
            "{e}"
        );
    }

    #[test]
    fn the_reported_sigmas_match_the_spread_over_noisy_trials() {
        let (left, _, right_from_left) = rig();
        let boards = boards();
        let trials = 40;
        let mut fx_err = Vec::new();
        let mut base_err = Vec::new();
        let mut sigma_fx = Vec::new();
        let mut sigma_tx = Vec::new();
        for t in 0..trials {
            let s =
                calibrate_stereo(&Board::LIBRARY, SIZE, &views(&boards, 0.1, 100 + t), &Options::default()).unwrap();
            fx_err.push(s.left.fx - left.fx);
            base_err.push(s.right_from_left.translation.x - right_from_left.translation.x);
            sigma_fx.push(s.left_sigma[0]);
            sigma_tx.push(s.rig_sigma[3]);
        }
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        // Over 40 trials the spread's estimate is good to about +-11% (1 sigma).
        for (name, spread, reported) in [("fx", rms(&fx_err), mean(&sigma_fx)), ("tx", rms(&base_err), mean(&sigma_tx))]
        {
            let ratio = spread / reported;
            assert!((0.7..1.4).contains(&ratio), "{name}: spread {spread:.3e}, reported sigma {reported:.3e}");
        }
    }
}
