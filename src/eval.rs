//! Evaluation of the vision front end against ground truth (the only code that reads it).

use crate::front_end::FrontEnd;
use crate::truth::TruthScene;
use mesh::StereoCalibration;
use nalgebra::Point3;
use serde::Serialize;
use vision::rectify::Rectification;

/// How matched disparities compare with the truth.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct DisparityStats {
    /// Matches with a ground-truth disparity (a surface behind the left edgel).
    pub evaluated: usize,
    /// Of those, within 0.5 px of the true disparity.
    pub within_0_5px: usize,
    /// Of those, more than 2 px off.
    pub wrong: usize,
}

impl DisparityStats {
    pub fn add(&mut self, other: &DisparityStats) {
        self.evaluated += other.evaluated;
        self.within_0_5px += other.within_0_5px;
        self.wrong += other.wrong;
    }

    pub fn within_fraction(&self) -> f64 {
        self.within_0_5px as f64 / self.evaluated.max(1) as f64
    }

    pub fn wrong_fraction(&self) -> f64 {
        self.wrong as f64 / self.evaluated.max(1) as f64
    }
}

/// Compares every match's disparity with the true one at its left edgel (the nearer surface's
/// at an occluding boundary).
pub fn disparity_stats(fe: &FrontEnd, truth: &TruthScene, calib: &StereoCalibration) -> DisparityStats {
    let rect = Rectification::new(calib);
    let mut stats = DisparityStats::default();
    for m in &fe.matches {
        let e = &fe.left.edgels[m.left as usize];
        let Some(d) = truth.disparity(&calib.left, &rect, e.x as f64, e.y as f64, e.orientation as f64) else {
            continue;
        };
        let err = (m.disparity as f64 - d).abs();
        stats.evaluated += 1;
        stats.within_0_5px += usize::from(err <= 0.5);
        stats.wrong += usize::from(err > 2.0);
    }
    stats
}

/// How the 3D lines compare with the models' true feature edges.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LineStats {
    /// Distance of each 3D line end from the nearest true feature edge, millimetres.
    pub endpoint_err_mm: Vec<f64>,
    /// Visible feature-edge length (in pieces >= 20 px long in the image), and how much of it a
    /// 3D line recovered, metres.
    pub visible_m: f64,
    pub recovered_m: f64,
}

impl LineStats {
    pub fn add(&mut self, other: &LineStats) {
        self.endpoint_err_mm.extend_from_slice(&other.endpoint_err_mm);
        self.visible_m += other.visible_m;
        self.recovered_m += other.recovered_m;
    }

    pub fn coverage(&self) -> f64 {
        self.recovered_m / self.visible_m.max(1e-12)
    }

    /// The `q` quantile (0-1) of the endpoint errors.
    pub fn endpoint_quantile(&self, q: f64) -> f64 {
        let mut v = self.endpoint_err_mm.clone();
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * q).round() as usize]
    }
}

fn point_segment_distance(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-18)).clamp(0.0, 1.0);
    (p - (a + ab * t)).norm()
}

/// Sample spacing along feature edges when measuring coverage, metres.
const COVERAGE_STEP_M: f64 = 0.001;
/// A feature-edge point counts as recovered by a 3D line within this distance...
const RECOVERED_WITHIN_M: f64 = 0.003;
/// ...running within this angle of the edge.
const RECOVERED_ANGLE_DEG: f64 = 10.0;
/// Visible runs shorter than this in the image do not count towards coverage.
const MIN_VISIBLE_RUN_PX: f64 = 20.0;

/// Compares 3D lines (in the left camera's frame) with the true feature edges of the scene's
/// objects; `left_depth` is the left camera's true depth map, for visibility.
pub fn line_stats(
    fe: &FrontEnd,
    scene: &sim::Scene,
    library: &mesh::Library,
    calib: &StereoCalibration,
    left_depth: &[f32],
) -> LineStats {
    let cam = &calib.left;
    let edges: Vec<(Point3<f64>, Point3<f64>)> = scene
        .objects
        .iter()
        .flat_map(|o| {
            library.models[&o.model].wireframe.iter().map(move |s| {
                let to_cam = cam.cam_from_world() * o.world_from_model;
                (to_cam * s.a, to_cam * s.b)
            })
        })
        .collect();
    let lines: Vec<(Point3<f64>, Point3<f64>)> = fe.lines3d.iter().map(|l| (l.start(), l.end())).collect();
    let mut stats = LineStats::default();
    for (a, b) in &lines {
        for p in [a, b] {
            let nearest = edges.iter().map(|(ea, eb)| point_segment_distance(p, ea, eb)).fold(f64::MAX, f64::min);
            stats.endpoint_err_mm.push(nearest * 1e3);
        }
    }
    let cos_max = RECOVERED_ANGLE_DEG.to_radians().cos();
    for (ea, eb) in &edges {
        let dir = (eb - ea).normalize();
        let steps = ((eb - ea).norm() / COVERAGE_STEP_M).ceil().max(1.0) as usize;
        // Runs of visible samples: (image length, metres, recovered metres).
        let mut run = (0.0, 0.0, 0.0);
        let mut last_px: Option<nalgebra::Point2<f64>> = None;
        let close_run = |run: &mut (f64, f64, f64), stats: &mut LineStats| {
            if run.0 >= MIN_VISIBLE_RUN_PX {
                stats.visible_m += run.1;
                stats.recovered_m += run.2;
            }
            *run = (0.0, 0.0, 0.0);
        };
        for k in 0..steps {
            let p = ea + (eb - ea) * ((k as f64 + 0.5) / steps as f64);
            let step_m = (eb - ea).norm() / steps as f64;
            let Some(px) = cam.project_cam(&p).filter(|q| visible(q, p.z, left_depth, cam)) else {
                close_run(&mut run, &mut stats);
                last_px = None;
                continue;
            };
            run.0 += last_px.map_or(0.0, |l| (px - l).norm());
            run.1 += step_m;
            let recovered = lines.iter().any(|(la, lb)| {
                let ldir = (lb - la).normalize();
                ldir.dot(&dir).abs() >= cos_max && point_segment_distance(&p, la, lb) <= RECOVERED_WITHIN_M
            });
            if recovered {
                run.2 += step_m;
            }
            last_px = Some(px);
        }
        close_run(&mut run, &mut stats);
    }
    stats
}

/// A point at depth `z` projecting to `px` is seen: some pixel within one of it in the true
/// depth map lies at its depth (a surface beside the edge is its own), and none is far nearer.
fn visible(px: &nalgebra::Point2<f64>, z: f64, depth: &[f32], cam: &mesh::PinholeCamera) -> bool {
    let (w, h) = (cam.width as i64, cam.height as i64);
    let (cx, cy) = (px.x.round() as i64, px.y.round() as i64);
    if cx < 1 || cy < 1 || cx >= w - 1 || cy >= h - 1 {
        return false;
    }
    let around = (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| depth[((cy + dy) * w + cx + dx) as usize] as f64));
    let (mut own, mut occluded) = (false, false);
    for d in around {
        own |= (d - z).abs() < 0.003;
        occluded |= d < z - 0.01;
    }
    own && !occluded
}
