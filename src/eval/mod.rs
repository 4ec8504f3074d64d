//! Evaluation apart from both sides of the socket: the vision front end's and the matcher's
//! results against ground truth (the only code that reads it).
//!
//! - [`truth`]: the truth itself: exact ray casts into the settled scene, the cameras as
//!   evaluation places them, and [`truth::AskTruth`], the server's evaluation-only request.
//! - [`batch`]: batches at scale: shards of a seed range, a JSON line per scene, merging.
//! - This file: disparity and coverage figures, located and false reports, quantiles and
//!   Wilson intervals.

pub mod batch;
pub mod truth;

use self::truth::{EvalCameras, TruthScene};
use crate::front_end::FrontEnd;
use nalgebra::Point3;
use serde::{Deserialize, Serialize};
use vision::front_end::rectify::Rectification;

/// How matched disparities compare with the truth.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
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

/// The left image's pixels on the arm (or the tool it holds) or within [`ARM_MARGIN_PX`] of it.
/// The cameras see the robot's column; its silhouettes, a box seen nearly edge-on, show the two
/// cameras different corners, so stereo gives them disparities 10 px off. The front end's
/// figures describe the workspace; what falls on the arm is counted apart.
#[derive(Debug, Clone)]
pub struct ArmMask {
    width: usize,
    height: usize,
    near: Vec<bool>,
}

/// How far round the arm's pixels the mask reaches: an edgel on its silhouette may lie on the
/// table's side of it.
pub const ARM_MARGIN_PX: usize = 3;

impl ArmMask {
    /// From the left frame's id map.
    pub fn from_ids(width: usize, height: usize, ids: &[u16]) -> ArmMask {
        let on_arm = |i: usize| ids[i] as u32 >= sim::render::ARM_ID_BASE || ids[i] as u32 == sim::render::TOOL_ID;
        let mut near = vec![false; width * height];
        let m = ARM_MARGIN_PX as isize;
        for y in 0..height {
            for x in 0..width {
                if !on_arm(y * width + x) {
                    continue;
                }
                for dy in -m..=m {
                    for dx in -m..=m {
                        let (xx, yy) = (x as isize + dx, y as isize + dy);
                        if (0..width as isize).contains(&xx) && (0..height as isize).contains(&yy) {
                            near[yy as usize * width + xx as usize] = true;
                        }
                    }
                }
            }
        }
        ArmMask { width, height, near }
    }

    /// Whether pixel `(x, y)` lies on or near the arm.
    pub fn covers(&self, x: f64, y: f64) -> bool {
        let (xi, yi) = (x.round(), y.round());
        xi >= 0.0
            && yi >= 0.0
            && (xi as usize) < self.width
            && (yi as usize) < self.height
            && self.near[yi as usize * self.width + xi as usize]
    }
}

/// Compares every match's disparity with the true one at its left edgel (the nearer surface's
/// at an occluding boundary): the workspace's matches, and apart those on the arm.
pub fn disparity_stats(
    fe: &FrontEnd,
    truth: &TruthScene,
    cams: &EvalCameras,
    arm: &ArmMask,
) -> (DisparityStats, DisparityStats) {
    let rect = Rectification::new(&cams.vision);
    let (mut workspace, mut on_arm) = (DisparityStats::default(), DisparityStats::default());
    for m in &fe.matches {
        let e = &fe.left.edgels[m.left as usize];
        let Some(d) = truth.disparity(cams, &rect, e.x as f64, e.y as f64, e.orientation as f64) else {
            continue;
        };
        let err = (m.disparity as f64 - d).abs();
        let stats = if arm.covers(e.x as f64, e.y as f64) { &mut on_arm } else { &mut workspace };
        stats.evaluated += 1;
        stats.within_0_5px += usize::from(err <= 0.5);
        stats.wrong += usize::from(err > 2.0);
    }
    (workspace, on_arm)
}

/// What became of each left edgel (but those `skip` leaves out: the arm's) that has a true disparity:
/// matched within 0.5 px of it, matched further off, unmatched though a right edgel within
/// 1 px of the true disparity was a candidate (lost to a rival in PMF's later steps), or
/// unmatched for the candidate test its would-be partners failed ([`pmf::Refusal`]). Counts by
/// name; the test that reads them says where the front end loses edges.
pub fn edgel_fates(
    fe: &FrontEnd,
    truth: &TruthScene,
    cams: &EvalCameras,
    skip: &dyn Fn(&vision::Edgel) -> bool,
) -> std::collections::BTreeMap<String, usize> {
    use vision::front_end::pmf::{PmfParams, refusal};
    let rect = Rectification::new(&cams.vision);
    let (disparity_min, disparity_max) = vision::front_end::disparity_range(
        &rect,
        vision::front_end::WORKSPACE_DEPTH_M.0,
        vision::front_end::WORKSPACE_DEPTH_M.1,
    );
    let params = PmfParams { disparity_min, disparity_max, ..PmfParams::default() };
    // The sliced front end keeps no whole-image list of rectified right edgels. Its grey
    // levels are mapped to the left camera's as PMF maps them before its side test.
    let right = rect.rectify_edgels(vision::front_end::rectify::Side::Right, &fe.right.edgels);
    let relation = vision::front_end::pmf::photometric_relation(&fe.left_rectified, &right, &fe.left_strings, &params);
    let right: Vec<vision::Edgel> = right.iter().map(|e| relation.map(e)).collect();
    let params = PmfParams { side_scatter: relation.scatter, ..params };
    let mut matched = vec![None; fe.left.edgels.len()];
    // PMF once more over the whole image, to tell a candidate PMF refused from a match dropped
    // after it (by figural continuity along the right strings or for lying on no 3D line).
    let mut pmf_choice = vec![None; fe.left.edgels.len()];
    for m in vision::front_end::pmf::pmf(&fe.left_rectified, &right, &fe.left_strings, &params) {
        pmf_choice[m.left as usize] = Some(m.disparity);
    }
    for m in &fe.matches {
        matched[m.left as usize] = Some(m.disparity);
    }
    let mut fates = std::collections::BTreeMap::new();
    for (i, e) in fe.left.edgels.iter().enumerate() {
        if skip(e) {
            continue;
        }
        let Some(d) = truth.disparity(cams, &rect, e.x as f64, e.y as f64, e.orientation as f64) else {
            continue;
        };
        let fate = match matched[i] {
            Some(md) if (md as f64 - d).abs() <= 0.5 => "matched_within_0_5px".to_string(),
            Some(_) => "matched_off".to_string(),
            None => match refusal(&fe.left_rectified[i], &right, d as f32, 1.0, &params) {
                None => match pmf_choice[i] {
                    Some(pd) if (pd as f64 - d).abs() <= 0.5 => "dropped_after_pmf".to_string(),
                    Some(_) => "rival_won".to_string(),
                    None => "candidate_unmatched".to_string(),
                },
                Some(why) => format!("{why:?}"),
            },
        };
        *fates.entry(fate).or_insert(0) += 1;
    }
    fates
}

/// How the 3D lines compare with the models' true feature edges.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LineStats {
    /// Distance of each 3D line end from the nearest true feature edge, millimetres.
    pub endpoint_err_mm: Vec<f64>,
    /// Visible feature-edge length (in pieces >= 20 px long in the image), and how much of it a
    /// 3D line recovered, metres.
    pub visible_m: f64,
    pub recovered_m: f64,
    /// 3D lines on the arm, left out of the above.
    pub arm_lines: usize,
    /// 3D lines (not on the arm) whose middle lies further than [`OFF_EDGE_M`] from every true
    /// feature edge: shadows' edges, the table's texture, silhouettes of curved nothing, or
    /// stereo's mistakes; and of those, the ones with both ends within [`OFF_EDGE_M`] of the
    /// true table top (a shadow or the texture on it).
    #[serde(default)]
    pub off_edge_lines: usize,
    #[serde(default)]
    pub off_edge_on_table: usize,
    /// 3D lines with both ends within [`OFF_EDGE_M`] of the true table top, on a part's edge
    /// (its bottom edges) or not.
    #[serde(default)]
    pub on_table_lines: usize,
    /// 3D lines the front end set apart as shadows or texture (`FrontEnd::set_apart`, not on
    /// the arm; none of the above counts them), and of those, the ones on no true feature edge.
    #[serde(default)]
    pub set_apart_lines: usize,
    #[serde(default)]
    pub set_apart_off_edges: usize,
}

impl LineStats {
    pub fn add(&mut self, other: &LineStats) {
        self.endpoint_err_mm.extend_from_slice(&other.endpoint_err_mm);
        self.visible_m += other.visible_m;
        self.recovered_m += other.recovered_m;
        self.arm_lines += other.arm_lines;
        self.off_edge_lines += other.off_edge_lines;
        self.off_edge_on_table += other.off_edge_on_table;
        self.on_table_lines += other.on_table_lines;
        self.set_apart_lines += other.set_apart_lines;
        self.set_apart_off_edges += other.set_apart_off_edges;
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
/// A 3D line whose middle is further than this from every true feature edge lies on none
/// (metres; the right lines' ends are a millimetre or two off, `endpoint_err_mm`).
pub const OFF_EDGE_M: f64 = 0.005;

/// Compares 3D lines (in the `cam` frame vision was given) with the true feature edges of the
/// scene's objects; `left_depth` is the true left camera's depth map, for visibility.
pub fn line_stats(
    fe: &FrontEnd,
    scene: &sim::Scene,
    library: &mesh::Library,
    cams: &EvalCameras,
    left_depth: &[f32],
    arm: &ArmMask,
) -> LineStats {
    let cam = &cams.vision.left;
    let truly = &cams.true_left;
    // Where vision believes its camera is, against where it is: a true point in vision's frame.
    let vision_from_true = cam.cam_from_world() * truly.pinhole.world_from_cam;
    let edges: Vec<(Point3<f64>, Point3<f64>)> = scene
        .objects
        .iter()
        .flat_map(|o| {
            library.models[&o.model].wireframe.iter().map(move |s| {
                let to_cam = truly.pinhole.cam_from_world() * o.world_from_model;
                (to_cam * s.a, to_cam * s.b)
            })
        })
        .collect();
    // Lines on the arm are no model's feature edges: counted apart.
    let on_arm = |a: &Point3<f64>, b: &Point3<f64>| {
        cam.project_cam(&nalgebra::center(a, b)).is_some_and(|px| arm.covers(px.x, px.y))
    };
    let mut stats = LineStats::default();
    let lines: Vec<(Point3<f64>, Point3<f64>)> = fe
        .lines3d
        .iter()
        .map(|l| (l.start(), l.end()))
        .filter(|(a, b)| {
            let arm_line = on_arm(a, b);
            stats.arm_lines += usize::from(arm_line);
            !arm_line
        })
        .collect();
    // The lines in the true camera's frame (where the truth edges are).
    let lines: Vec<(Point3<f64>, Point3<f64>)> =
        lines.iter().map(|(a, b)| (vision_from_true.inverse() * a, vision_from_true.inverse() * b)).collect();
    let nearest_edge =
        |p: &Point3<f64>| edges.iter().map(|(ea, eb)| point_segment_distance(p, ea, eb)).fold(f64::MAX, f64::min);
    // The world frame's z = 0 is the table's top.
    let on_table = |p: &Point3<f64>| (truly.pinhole.world_from_cam * p).z.abs() <= OFF_EDGE_M;
    for (a, b) in &lines {
        for p in [a, b] {
            stats.endpoint_err_mm.push(nearest_edge(p) * 1e3);
        }
        let flat = on_table(a) && on_table(b);
        stats.on_table_lines += usize::from(flat);
        if nearest_edge(&nalgebra::center(a, b)) > OFF_EDGE_M {
            stats.off_edge_lines += 1;
            stats.off_edge_on_table += usize::from(flat);
        }
    }
    for l in fe.set_apart.iter().filter(|l| !on_arm(&l.start(), &l.end())) {
        let middle = vision_from_true.inverse() * nalgebra::center(&l.start(), &l.end());
        stats.set_apart_lines += 1;
        stats.set_apart_off_edges += usize::from(nearest_edge(&middle) > OFF_EDGE_M);
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
            let Some(px) = truly.project_cam(&p).filter(|q| visible(q, p.z, left_depth, &truly.pinhole)) else {
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

pub use mesh::model::symmetries;

/// Position (m, of the model origin) and rotation (rad) error of a located pose, the smallest
/// over the model's symmetries.
pub fn pose_error(
    located: &nalgebra::Isometry3<f64>,
    truth: &nalgebra::Isometry3<f64>,
    symmetries: &[nalgebra::Isometry3<f64>],
) -> (f64, f64) {
    symmetries
        .iter()
        .map(|g| {
            let t = truth * g;
            ((located.translation.vector - t.translation.vector).norm(), located.rotation.angle_to(&t.rotation))
        })
        .fold((f64::MAX, f64::MAX), |best, e| if e.0 + 0.05 * e.1 < best.0 + 0.05 * best.1 { e } else { best })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against the Wilson intervals of the literature (Newcombe 1998, table I: 81/263 gives
    /// 0.2553-0.3662) and worked by hand (5/10: 0.2366-0.7634; 0/10: 0-0.2775).
    #[test]
    fn wilson_intervals_match_the_literature() {
        let close = |got: [f64; 2], want: [f64; 2]| (got[0] - want[0]).abs() < 1e-4 && (got[1] - want[1]).abs() < 1e-4;
        assert!(close(wilson95(81, 263), [0.2553, 0.3662]), "{:?}", wilson95(81, 263));
        assert!(close(wilson95(5, 10), [0.2366, 0.7634]), "{:?}", wilson95(5, 10));
        assert!(close(wilson95(0, 10), [0.0, 0.2775]), "{:?}", wilson95(0, 10));
        assert_eq!(wilson95(0, 0), [0.0, 1.0]);
        let mut doc = serde_json::json!({ "a": 0.5, "arm": { "b": 0.0 } });
        add_intervals(&mut doc, &[("a", 5, 10), ("arm.b", 0, 10)]);
        assert!(close(serde_json::from_value(doc["a_ci95"].clone()).unwrap(), [0.2366, 0.7634]), "{doc}");
        assert!(doc["arm"]["b_ci95"].is_array(), "{doc}");
    }

    #[test]
    fn symmetry_groups_of_the_library() {
        let lib = mesh::Library::load_default().unwrap();
        let order = |name: &str| symmetries(lib.get(name).unwrap()).len();
        assert_eq!(order("block"), 4, "a box: identity and three half turns");
        assert_eq!(order("hex_prism"), 12, "a hexagonal prism: 6 turns about its axis, 6 flips");
        assert_eq!(order("widget"), 1);
        // Mirror-symmetric only (no proper rotation maps them onto themselves).
        assert_eq!(order("wedge"), 1);
        assert_eq!(order("l_bracket"), 1);
        // Profiles symmetric about their y axis, extruded: a half turn about that axis.
        assert_eq!(order("t_piece"), 2);
        assert_eq!(order("u_channel"), 2);
    }

    /// A false report names where it puts its model in the world: the pose vision gave, in the
    /// camera it was given, carried into the world through that camera's place (worked here
    /// from a world point chosen first), and what lay nearest.
    #[test]
    fn a_false_report_says_where_in_the_world_it_lies() {
        use nalgebra::{Isometry3, Point3, Vector3};
        let cam = mesh::PinholeCamera::looking_at(
            (512, 512),
            1000.0,
            [255.5, 255.5],
            Point3::new(0.1, -0.6, 0.5),
            Point3::origin(),
            Vector3::z(),
        );
        let settle = sim::physics::SettleReport {
            simulated_s: 1.0,
            steps: 60,
            at_rest: true,
            max_linear_speed: 0.0,
            max_angular_speed: 0.0,
            max_contact_depth: 0.0,
            drops: 1,
        };
        let block = sim::scene::SceneObject {
            id: 0,
            model: "block".into(),
            world_from_model: Isometry3::translation(0.02, 0.03, 0.0125),
        };
        let scene = sim::Scene { seed: 1, statics: Vec::new(), objects: vec![block], arm: Vec::new(), settle };
        let truths = vec![(0, cam.cam_from_world() * scene.objects[0].world_from_model)];
        let world_from_report = Isometry3::translation(-0.05, 0.07, 0.02);
        let report = vision::matcher::Located {
            model: "wedge".into(),
            cam_from_model: cam.cam_from_world() * world_from_report,
            support: 0.01,
            support_fraction: 0.1,
            scene_lines: Vec::new(),
            image_support: 0.6,
            grasps: Vec::new(),
        };
        let f = false_report((3, &report), &scene.objects, &truths, &[Isometry3::identity()], &cam);
        let want = [-0.05, 0.07, 0.02];
        assert!(f.world_m.iter().zip(want).all(|(got, want)| (got - want).abs() < 1e-9), "{:?}", f.world_m);
        assert_eq!(f.same_model, None, "no wedge in the scene");
        assert_eq!(f.index, 3, "the report's place in the matcher's list");
        let (id, model, mm): (usize, String, f64) = f.nearest.clone().unwrap();
        let apart = (Vector3::<f64>::new(-0.05, 0.07, 0.02) - Vector3::new(0.02, 0.03, 0.0125)).norm() * 1e3;
        assert_eq!((id, model.as_str()), (0, "block"));
        assert!((mm - apart).abs() < 1e-6, "{mm} mm, {apart} mm apart");
    }
}

/// How located objects compare with the truth.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LocateStats {
    /// Objects with at least 30% of their feature-edge length visible, and how many of those
    /// were located.
    pub eligible: usize,
    pub located: usize,
    /// All reports, and those matching no object (wrong place, wrong model, or a second report
    /// of one object).
    pub reports: usize,
    pub false_positives: usize,
    /// Errors of the correct reports (over the model's symmetries).
    pub pos_err_mm: Vec<f64>,
    pub rot_err_deg: Vec<f64>,
    /// Per model: eligible objects and how many of them were located.
    pub by_model: std::collections::BTreeMap<String, [usize; 2]>,
    /// Each false report, and each eligible object not located, to look into.
    pub false_reports: Vec<FalseReport>,
    pub missed: Vec<Missed>,
}

/// A report that matched no object: what it was, and what lay nearest.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FalseReport {
    pub model: String,
    pub support_fraction: f64,
    pub image_support: f64,
    /// The nearest object of the same model (taken or not): its id, position and rotation
    /// errors (mm, deg, over the symmetries); `None` when the scene has none.
    pub same_model: Option<(usize, f64, f64)>,
    /// The nearest object of any model to the report's origin: its id, model, distance (mm).
    pub nearest: Option<(usize, String, f64)>,
    /// Where the report puts the model's origin in the world (metres), through the calibration
    /// vision was given: to see where in the cell false reports gather.
    #[serde(default)]
    pub world_m: [f64; 3],
    /// The report's place in the matcher's list of reports for its scene.
    #[serde(default)]
    pub index: usize,
    /// The matcher's own measures at the report's pose (as `Missed::at_truth` at an object's),
    /// to set beside those of the object it was taken for.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub as_reported: Option<AtTruth>,
    /// With `--doubt`: whether a turn of the part fits the report as well
    /// (`vision::matcher::polish::doubt`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub in_doubt: Option<bool>,
}

/// An eligible object that was not located.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Missed {
    pub id: usize,
    pub model: String,
    pub visible_fraction: f64,
    /// The matcher's own measures at the object's true pose (through the calibration vision
    /// was given), judged afterwards: whether the evidence was there to be found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at_truth: Option<AtTruth>,
}

/// What the matcher's measures say of a pose: the share of the wireframe along 3D lines and
/// the model lines they lie along ([`vision::matcher::support_at`]), and the share of the
/// camera-facing wireframe along each image's edgels ([`vision::matcher::verify::image_support`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AtTruth {
    pub support_fraction: f64,
    pub lines: usize,
    pub image_support: f64,
    pub image_support_right: Option<f64>,
}

/// A report counts as correct within these.
pub const CORRECT_POS_M: f64 = 0.01;
pub const CORRECT_ROT_DEG: f64 = 5.0;

impl LocateStats {
    pub fn add(&mut self, o: &LocateStats) {
        self.eligible += o.eligible;
        self.located += o.located;
        self.reports += o.reports;
        self.false_positives += o.false_positives;
        self.pos_err_mm.extend_from_slice(&o.pos_err_mm);
        self.false_reports.extend_from_slice(&o.false_reports);
        self.missed.extend_from_slice(&o.missed);
        self.rot_err_deg.extend_from_slice(&o.rot_err_deg);
        for (model, [e, l]) in &o.by_model {
            let t = self.by_model.entry(model.clone()).or_default();
            t[0] += e;
            t[1] += l;
        }
    }
}

/// The 95% Wilson score interval of a fraction of `k` in `n` trials (`[0, 1]` when `n` is 0).
/// It assumes independent trials; matches and parts of one scene are not quite, so read it as
/// a lower bound on the uncertainty.
pub fn wilson95(k: usize, n: usize) -> [f64; 2] {
    if n == 0 {
        return [0.0, 1.0];
    }
    const Z: f64 = 1.959_963_984_540_054;
    let (n, p) = (n as f64, k as f64 / n as f64);
    let denominator = 1.0 + Z * Z / n;
    let centre = (p + Z * Z / (2.0 * n)) / denominator;
    let half = Z * (p * (1.0 - p) / n + Z * Z / (4.0 * n * n)).sqrt() / denominator;
    [(centre - half).max(0.0), (centre + half).min(1.0)]
}

/// Puts `{key}_ci95` beside each fraction `key` of a report object, from its count: `(key, k,
/// n)`. A key with a dot (`arm.wrong_matches`) is one in a nested object.
pub fn add_intervals(report: &mut serde_json::Value, fractions: &[(&str, usize, usize)]) {
    for &(key, k, n) in fractions {
        let (object, name) = match key.split_once('.') {
            Some((outer, inner)) => (&mut report[outer], inner),
            None => (&mut *report, key),
        };
        object[format!("{name}_ci95")] = serde_json::json!(wilson95(k, n));
    }
}

/// The `q` quantile of `v` (NaN when empty).
pub fn quantile(v: &[f64], q: f64) -> f64 {
    let mut v = v.to_vec();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Fraction of an object's feature-edge length the left camera sees (`depth`: its depth map, metres).
pub fn visible_fraction(
    model: &mesh::Model,
    cam_from_model: &nalgebra::Isometry3<f64>,
    cam: &mesh::LensCamera,
    depth: &[f32],
) -> f64 {
    let (mut seen, mut all) = (0.0, 0.0);
    for s in &model.wireframe {
        let (a, b) = (cam_from_model * s.a, cam_from_model * s.b);
        let steps = ((b - a).norm() / COVERAGE_STEP_M).ceil().max(1.0) as usize;
        let step = (b - a).norm() / steps as f64;
        for k in 0..steps {
            let p = a + (b - a) * ((k as f64 + 0.5) / steps as f64);
            all += step;
            if cam.project_cam(&p).is_some_and(|q| visible(&q, p.z, depth, &cam.pinhole)) {
                seen += step;
            }
        }
    }
    seen / all.max(1e-12)
}

/// Compares located objects (poses in the left camera's frame) with the scene's truth. The
/// objects in view are those the left camera's depth map (metres) shows 30% of the feature
/// edges of; without a depth map, every object.
pub fn locate_stats(
    located: &[vision::matcher::Located],
    objects: &[sim::scene::SceneObject],
    library: &mesh::Library,
    cams: &EvalCameras,
    left_depth: Option<&[f32]>,
    symmetry: &std::collections::BTreeMap<String, Vec<nalgebra::Isometry3<f64>>>,
) -> LocateStats {
    // Reports are in the frame of the camera vision was given: the truth is put there through
    // the world, as a user who took that calibration on trust would put a report in the world.
    let cam = &cams.vision.left;
    let truths: Vec<(usize, nalgebra::Isometry3<f64>)> =
        objects.iter().enumerate().map(|(i, o)| (i, cam.cam_from_world() * o.world_from_model)).collect();
    let truly = &cams.true_left;
    // Without a depth map every object counts as in view.
    let visible: Vec<f64> = objects
        .iter()
        .map(|o| {
            let pose = truly.pinhole.cam_from_world() * o.world_from_model;
            left_depth.map_or(1.0, |depth| visible_fraction(&library.models[&o.model], &pose, truly, depth))
        })
        .collect();
    let eligible: Vec<bool> = visible.iter().map(|v| *v >= 0.3).collect();
    let mut stats =
        LocateStats { eligible: eligible.iter().filter(|e| **e).count(), reports: located.len(), ..Default::default() };
    for (o, &e) in objects.iter().zip(&eligible) {
        stats.by_model.entry(o.model.clone()).or_default()[0] += usize::from(e);
    }
    let mut taken = vec![false; objects.len()];
    for (index, loc) in located.iter().enumerate() {
        let best = truths
            .iter()
            .filter(|(i, _)| objects[*i].model == loc.model && !taken[*i])
            .map(|(i, pose)| (*i, pose_error(&loc.cam_from_model, pose, &symmetry[&loc.model])))
            .min_by(|a, b| a.1.0.total_cmp(&b.1.0));
        match best {
            Some((i, (pos, rot))) if pos <= CORRECT_POS_M && rot.to_degrees() <= CORRECT_ROT_DEG => {
                taken[i] = true;
                stats.located += usize::from(eligible[i]);
                stats.by_model.entry(loc.model.clone()).or_default()[1] += usize::from(eligible[i]);
                stats.pos_err_mm.push(pos * 1e3);
                stats.rot_err_deg.push(rot.to_degrees());
            }
            _ => {
                stats.false_positives += 1;
                stats.false_reports.push(false_report((index, loc), objects, &truths, &symmetry[&loc.model], cam));
            }
        }
    }
    for (i, o) in objects.iter().enumerate().filter(|(i, _)| eligible[*i] && !taken[*i]) {
        stats.missed.push(Missed { id: i, model: o.model.clone(), visible_fraction: visible[i], at_truth: None });
    }
    stats
}

/// What lay nearest a report that matched nothing.
fn false_report(
    (index, loc): (usize, &vision::matcher::Located),
    objects: &[sim::scene::SceneObject],
    truths: &[(usize, nalgebra::Isometry3<f64>)],
    symmetry: &[nalgebra::Isometry3<f64>],
    cam: &mesh::PinholeCamera,
) -> FalseReport {
    let same_model = truths
        .iter()
        .filter(|(i, _)| objects[*i].model == loc.model)
        .map(|(i, pose)| {
            let (pos, rot) = pose_error(&loc.cam_from_model, pose, symmetry);
            (*i, pos * 1e3, rot.to_degrees())
        })
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let nearest = truths
        .iter()
        .map(|(i, pose)| (*i, (pose.translation.vector - loc.cam_from_model.translation.vector).norm() * 1e3))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, d)| (i, objects[i].model.clone(), d));
    FalseReport {
        model: loc.model.clone(),
        support_fraction: loc.support_fraction,
        image_support: loc.image_support,
        same_model,
        nearest,
        world_m: (cam.world_from_cam * loc.cam_from_model).translation.vector.into(),
        index,
        as_reported: None,
        in_doubt: None,
    }
}
