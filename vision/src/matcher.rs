//! The model matcher (Pollard, Porrill, Mayhew & Frisby, as TINA uses it), for one model.
//!
//! - The model is its wireframe: directed 3D segments, with the grasp positions of the library.
//! - Featural parallelism: the model is split into six characteristic views (the lines on faces
//!   turned towards a viewer looking along one of the model's axes); a subordinate matcher per
//!   view searches the scene, all in parallel, and the virtual matcher ([`locate`]) keeps the
//!   best of their hypotheses and looks again for further instances. (The views overlap so
//!   much that, their shared pairs tabled once, most of the work falls to the first.)
//! - Pairwise relations (the angle between two lines, their perpendicular separation and where
//!   along each the closest approach falls, as in Grimson & Lozano-Perez's tables) are tabled
//!   per view for the pairs that matter: each focus line (the view's longest in each direction
//!   by turns, in the manner of Bolles) with its feature group (the view's lines not parallel
//!   to it); pairs that the model's symmetry makes equivalent are tabled once.
//! - Hypotheses: a scene pair congruent with a focus pair, within tolerances that let fragments
//!   and partly seen lines qualify, gives a pose by least squares ([`crate::pose_fit`]).
//! - Each hypothesis is ranked by the support its pose finds: the length of scene lines lying
//!   along the transformed model lines. The best dozen are refined on their supporting sets and
//!   verified in order of that support times the image evidence ([`crate::verify`]): enough of
//!   the model seen, along enough lines, and along the left image's edgels; the pose of the one
//!   that passes is refined on the image too ([`crate::image_fit`]). Further instances come
//!   from the same hypotheses rescored without the lines already explained.
//!
//! Scene lines come from stereo with no particular direction, so each is used both ways round.

use crate::pose_fit::{
    DirectionPair, PointOnLine, pose_from_lines, rotation_from_two_directions, translation_from_points,
};
use crate::support::{FreeLines, NearLines, model_lines_of, scene_lines_of, support, support_score};
pub use crate::support::{correspondences_at, support_at};
use nalgebra::{Isometry3, Point3, Vector3};
use serde::{Deserialize, Serialize};

/// A straight 3D segment with its unit direction and length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Seg {
    pub a: Point3<f64>,
    pub b: Point3<f64>,
    pub dir: Vector3<f64>,
    pub len: f64,
}

impl Seg {
    pub fn new(a: Point3<f64>, b: Point3<f64>) -> Seg {
        let d = b - a;
        let len = d.norm();
        Seg { a, b, dir: d / len.max(1e-12), len }
    }

    pub fn transformed(&self, pose: &Isometry3<f64>) -> Seg {
        Seg::new(pose * self.a, pose * self.b)
    }
}

/// A model as the matcher sees it.
#[derive(Debug, Clone)]
pub struct MatcherModel {
    pub name: String,
    pub lines: Vec<Seg>,
    /// Outward normals of the faces meeting along each line: the line can be seen only from
    /// where one of them faces the camera.
    pub faces: Vec<Vec<Vector3<f64>>>,
    /// The solid's surface, triangle by triangle (model frame).
    pub triangles: Vec<[Point3<f64>; 3]>,
    /// Points filling the solid, on a grid (model frame): what two reports may not share.
    pub(crate) interior: Vec<Point3<f64>>,
    /// The solid's bounding box (model frame): a point outside it is not inside the solid.
    pub(crate) bounds: (Point3<f64>, Point3<f64>),
    /// Grasp positions: `model_from_gripper` and jaw opening (metres).
    pub grasps: Vec<(Isometry3<f64>, f64)>,
    pub total_length: f64,
    /// Centre and radius of a sphere holding the wireframe.
    pub(crate) sphere: (Point3<f64>, f64),
    /// The lines' indices, longest first (the order support is counted in).
    pub(crate) longest_first: Vec<usize>,
    /// The characteristic views' focus pairs, tabled on the first search (they depend only on
    /// the model and the number of focus lines, which are kept with them).
    views: std::sync::OnceLock<(usize, Vec<Vec<FocusPair>>)>,
    /// The lines near each cell of a grid over the model, laid out on the first search for its
    /// support distance (kept with it).
    pub(crate) grid: std::sync::OnceLock<crate::support::LineGrid>,
}

impl MatcherModel {
    pub fn from_model(m: &mesh::Model) -> MatcherModel {
        let lines: Vec<Seg> = m.wireframe.iter().map(|s| Seg::new(s.a, s.b)).collect();
        let faces = lines.iter().map(|l| faces_along(&m.mesh, l)).collect();
        let n = (2 * lines.len()).max(1) as f64;
        let centre = Point3::from(lines.iter().map(|l| l.a.coords + l.b.coords).sum::<Vector3<f64>>() / n);
        let radius = lines.iter().flat_map(|l| [l.a, l.b]).map(|p| (p - centre).norm()).fold(0.0, f64::max);
        let mut longest_first: Vec<usize> = (0..lines.len()).collect();
        longest_first.sort_by(|&a, &b| lines[b].len.total_cmp(&lines[a].len));
        let triangles: Vec<[Point3<f64>; 3]> = (0..m.mesh.triangles.len()).map(|t| m.mesh.corners(t)).collect();
        let bounds = m.mesh.bounds().unwrap_or((Point3::origin(), Point3::origin()));
        MatcherModel {
            interior: interior_points(bounds, &triangles),
            bounds,
            sphere: (centre, radius),
            longest_first,
            name: m.name.clone(),
            faces,
            triangles,
            total_length: lines.iter().map(|l| l.len).sum(),
            grasps: m.grasps.iter().map(|g| (g.model_from_gripper, g.opening)).collect(),
            lines,
            views: std::sync::OnceLock::new(),
            grid: std::sync::OnceLock::new(),
        }
    }
}

/// Spacing of the grid of points that fills a model (metres).
const INTERIOR_STEP: f64 = 0.004;

/// The points of a grid over a solid's bounds that lie inside its surface `triangles` (grid nodes fall half a step
/// in from the bounds, off the planes of the faces).
fn interior_points((lo, hi): (Point3<f64>, Point3<f64>), triangles: &[[Point3<f64>; 3]]) -> Vec<Point3<f64>> {
    let steps = (hi - lo).map(|e| (e / INTERIOR_STEP).ceil().max(1.0) as usize);
    let mut out = Vec::new();
    for i in 0..steps.x {
        for j in 0..steps.y {
            for k in 0..steps.z {
                let p = lo + Vector3::new(i as f64 + 0.5, j as f64 + 0.5, k as f64 + 0.5) * INTERIOR_STEP;
                if mesh::trimesh::encloses(triangles, &p) {
                    out.push(p);
                }
            }
        }
    }
    out
}

/// Normals of the mesh faces that have an edge lying along `line`.
fn faces_along(mesh: &mesh::TriMesh, line: &Seg) -> Vec<Vector3<f64>> {
    let on_line = |p: &Point3<f64>| {
        let w = p - line.a;
        (w - line.dir * w.dot(&line.dir)).norm() < 1e-7
    };
    let mut normals: Vec<Vector3<f64>> = Vec::new();
    for t in 0..mesh.triangles.len() {
        let c = mesh.corners(t);
        let along = (0..3).any(|k| on_line(&c[k]) && on_line(&c[(k + 1) % 3]));
        let n = mesh.face_normal(t);
        if along && normals.iter().all(|m| (m - n).norm() > 1e-6) {
            normals.push(n);
        }
    }
    normals
}

impl MatcherModel {
    /// Centre (mean of the line ends) and radius of a sphere holding the wireframe.
    pub fn bounding_sphere(&self) -> (Point3<f64>, f64) {
        self.sphere
    }

    /// Where a scene line must lie to support the model at `pose`: both its ends within
    /// `support_distance` of the wireframe, hence its midpoint within the returned distance of
    /// the returned centre.
    pub(crate) fn reach_at(&self, pose: &Isometry3<f64>, p: &MatchParams) -> (Point3<f64>, f64) {
        (pose * self.sphere.0, self.sphere.1 + p.support_distance)
    }

    /// Whether line `k` has a face turned towards a camera at the origin, with the model at
    /// `pose` (lines of no face always do): only such lines can be seen.
    pub fn faces_camera(&self, k: usize, pose: &Isometry3<f64>) -> bool {
        let (line, faces) = (&self.lines[k], &self.faces[k]);
        let mid = pose * nalgebra::center(&line.a, &line.b);
        faces.is_empty() || faces.iter().any(|n| (pose.rotation * n).dot(&-mid.coords) > 0.0)
    }

    /// Wireframe length a camera at the origin could see with the model at `pose` (lines with a
    /// face towards the camera; other objects may still hide them).
    pub fn visible_length(&self, pose: &Isometry3<f64>) -> f64 {
        (0..self.lines.len()).filter(|&k| self.faces_camera(k, pose)).map(|k| self.lines[k].len).sum()
    }
}

/// The matcher's tolerances and limits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MatchParams {
    /// Pair angles must agree within this (radians).
    pub angle_tolerance: f64,
    /// Pair separations must agree within this (metres).
    pub separation_tolerance: f64,
    /// A scene line supports a model line when both its ends lie within this distance of it
    /// (metres) and it runs within `angle_tolerance` of it.
    pub support_distance: f64,
    /// Scene lines shorter than this do not seed hypotheses (metres).
    pub min_seed_length: f64,
    /// How many of a characteristic view's longest lines serve as its focus features.
    pub focus_lines: usize,
    /// A located object must have this fraction of its wireframe length seen (measured: as a
    /// fraction of the length its pose turns towards the camera instead, every threshold found
    /// fewer objects for the same false reports)...
    pub min_support_fraction: f64,
    /// ...along at least this many model lines.
    pub min_support_lines: usize,
    /// Instances of one model sought at most.
    pub max_instances: usize,
    /// With the image at hand, a located object's camera-facing wireframe must run along
    /// edgels for at least this fraction of its length.
    pub min_image_support: f64,
}

impl Default for MatchParams {
    fn default() -> Self {
        MatchParams {
            angle_tolerance: 0.1,
            separation_tolerance: 0.004,
            support_distance: 0.003,
            min_seed_length: 0.012,
            focus_lines: 8,
            min_support_fraction: 0.15,
            min_support_lines: 3,
            max_instances: 3,
            min_image_support: 0.5,
        }
    }
}

/// One located instance of a model.
#[derive(Debug, Clone, PartialEq)]
pub struct Located {
    pub model: String,
    pub cam_from_model: Isometry3<f64>,
    /// Matched scene length, metres, and as a fraction of the model's wireframe length.
    pub support: f64,
    pub support_fraction: f64,
    /// Indices of the scene lines that support it.
    pub scene_lines: Vec<usize>,
    /// Fraction of its camera-facing wireframe that runs along edgels in the left image (1 when
    /// not verified in the image).
    pub image_support: f64,
    /// The model's grasp positions in the `cam` frame: `cam_from_gripper` and the jaw opening
    /// (metres).
    pub grasps: Vec<(Isometry3<f64>, f64)>,
}

/// Acute angle between two lines (directions up to sign).
pub(crate) fn line_angle(u: &Vector3<f64>, v: &Vector3<f64>) -> f64 {
    u.dot(v).abs().min(1.0).acos()
}

/// Distance between two infinite lines through `p` along `u` and `q` along `v`.
fn separation(p: &Point3<f64>, u: &Vector3<f64>, q: &Point3<f64>, v: &Vector3<f64>) -> f64 {
    let n = u.cross(v);
    let s = n.norm();
    if s < 1e-9 {
        let w = q - p;
        (w - u * w.dot(u)).norm()
    } else {
        (q - p).dot(&n).abs() / s
    }
}

/// Where along each of two non-parallel lines (from `p` along `u`, from `q` along `v`) their
/// closest approach falls.
fn closest_params(p: &Point3<f64>, u: &Vector3<f64>, q: &Point3<f64>, v: &Vector3<f64>) -> (f64, f64) {
    let w = p - q;
    let (b, d, e) = (u.dot(v), u.dot(&w), v.dot(&w));
    let den = 1.0 - b * b;
    if den < 1e-12 {
        return (0.0, 0.0);
    }
    ((b * e - d) / den, (e - b * d) / den)
}

/// Whether a fragment of length `frag` whose closest approach to its partner falls at `t` from
/// its start can lie, running the same way, on a model line of length `len` whose closest
/// approach falls at `m`: the fragment is some stretch of the model line.
fn fits_along(t: f64, frag: f64, m: f64, len: f64, tol: f64) -> bool {
    frag <= len + tol && t >= m - (len - frag) - tol && t <= m + tol
}

/// The pose from correspondences, directions signed to agree with `pose`.
fn fit(
    model: &MatcherModel,
    scene: &[Seg],
    pairs: &[(usize, usize, f64)],
    pose: &Isometry3<f64>,
) -> Option<Isometry3<f64>> {
    let mut dirs = Vec::new();
    let mut points = Vec::new();
    for &(i, j, w) in pairs {
        let (ml, sl) = (&model.lines[i], &scene[j]);
        let sign = if (pose.rotation * ml.dir).dot(&sl.dir) >= 0.0 { 1.0 } else { -1.0 };
        dirs.push(DirectionPair { model: ml.dir, scene: sl.dir * sign, weight: w });
        for x in [sl.a, sl.b] {
            points.push(PointOnLine { scene: x, model_point: ml.a, model_direction: ml.dir, weight: w });
        }
    }
    pose_from_lines(&dirs, &points)
}

/// A focus line and one of its feature group, with their relations: angle, separation, and
/// where along each their closest approach falls.
#[derive(Debug, Clone, Copy)]
struct FocusPair {
    focus: usize,
    partner: usize,
    angle: f64,
    separation: f64,
    at_focus: f64,
    at_partner: f64,
}

/// The focus pairs among `lines`: each focus line (the longest of them) with its feature group
/// (the lines not near-parallel to it). A pair that the model's own symmetry maps onto a pair
/// already tabled (in `tabled` or among the new ones), or the same two lines the other way
/// round, is left out: the hypotheses it would give are the same poses (up to the symmetry,
/// which is as correct), and each costs a support evaluation.
fn focus_pairs_among(model: &MatcherModel, lines: &[usize], p: &MatchParams, tabled: &[FocusPair]) -> Vec<FocusPair> {
    let mut out: Vec<FocusPair> = Vec::new();
    for i in focus_lines(model, lines, p.focus_lines) {
        for &k in lines {
            let (li, lk) = (&model.lines[i], &model.lines[k]);
            let angle = line_angle(&li.dir, &lk.dir);
            let seen = |f: &FocusPair| (f.focus == k && f.partner == i) || (f.focus == i && f.partner == k);
            if k == i || angle <= 0.35 || out.iter().chain(tabled).any(seen) {
                continue;
            }
            let (at_focus, at_partner) = closest_params(&li.a, &li.dir, &lk.a, &lk.dir);
            let separation = separation(&li.a, &li.dir, &lk.a, &lk.dir);
            let pair = FocusPair { focus: i, partner: k, angle, separation, at_focus, at_partner };
            if !out.iter().chain(tabled).any(|f| symmetric_images(model, f, &pair)) {
                out.push(pair);
            }
        }
    }
    out
}

/// The focus lines among `lines`: the longest, taken by turns from each direction the lines
/// run in (longest direction first), so that a view's focus lines do not all run one way.
/// Stereo recovers no edge near the rasters' direction; when the focus lines all ran along
/// it (the L-bracket's 70 and 55 mm edges are parallel), the object could not be seeded at all.
fn focus_lines(model: &MatcherModel, lines: &[usize], count: usize) -> Vec<usize> {
    let mut order = lines.to_vec();
    order.sort_by(|&a, &b| model.lines[b].len.total_cmp(&model.lines[a].len));
    // Group the lines by direction, each group longest first; the groups in order of their longest.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for i in order {
        let d = &model.lines[i].dir;
        match groups.iter_mut().find(|g| line_angle(&model.lines[g[0]].dir, d) < 0.35) {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    let mut out = Vec::new();
    for round in 0.. {
        let before = out.len();
        out.extend(groups.iter().filter_map(|g| g.get(round)).take(count - out.len()));
        if out.len() == count || out.len() == before {
            break;
        }
    }
    out
}

/// Characteristic views: for each of the model's six axis directions, the lines on faces that
/// a viewer looking from near there can see, with the focus pairs among them (pairs an earlier
/// view tabled are not tabled again). A subordinate matcher searches for each view.
fn characteristic_views(model: &MatcherModel, p: &MatchParams) -> Vec<Vec<FocusPair>> {
    let mut tabled: Vec<FocusPair> = Vec::new();
    let mut views = Vec::new();
    for axis in 0..3 {
        for sign in [1.0, -1.0] {
            let towards = Vector3::ith(axis, sign);
            let lines: Vec<usize> = (0..model.lines.len())
                .filter(|&i| model.faces[i].is_empty() || model.faces[i].iter().any(|n| n.dot(&towards) > VIEW_FACING))
                .collect();
            let mut pairs = focus_pairs_among(model, &lines, p, &tabled);
            tabled.extend_from_slice(&pairs);
            // By separation, so that a scene pair finds the focus pairs it may match by bisection.
            pairs.sort_by(|a, b| a.separation.total_cmp(&b.separation));
            views.push(pairs);
        }
    }
    views
}

/// A face belongs to a view when its normal is within about 96 deg of the view direction: a
/// viewer above an object lying flat sees its top and, obliquely, its sides, and the pairs that
/// seed hypotheses often join a top edge to a side edge.
const VIEW_FACING: f64 = -0.1;

/// Whether a rigid motion that takes pair `b`'s lines onto pair `a`'s (ends to ends) maps the
/// whole wireframe onto itself.
fn symmetric_images(model: &MatcherModel, a: &FocusPair, b: &FocusPair) -> bool {
    const EXACT: f64 = 1e-6;
    let congruent = (a.angle - b.angle).abs() < EXACT
        && (a.separation - b.separation).abs() < EXACT
        && (model.lines[a.focus].len - model.lines[b.focus].len).abs() < EXACT
        && (model.lines[a.partner].len - model.lines[b.partner].len).abs() < EXACT;
    if !congruent {
        return false;
    }
    // Either end of each line may map onto either end of its image.
    let ends = |s: &Seg| [(s.a, s.b), (s.b, s.a)];
    let (af, ap) = (&model.lines[a.focus], &model.lines[a.partner]);
    for (fa, fb) in ends(&model.lines[b.focus]) {
        for (pa, pb) in ends(&model.lines[b.partner]) {
            let from = Seg::new(fa, fb);
            let dirs = [
                DirectionPair { model: from.dir, scene: af.dir, weight: 1.0 },
                DirectionPair { model: Seg::new(pa, pb).dir, scene: ap.dir, weight: 1.0 },
            ];
            let points = [
                PointOnLine { scene: af.a, model_point: fa, model_direction: from.dir, weight: 1.0 },
                PointOnLine { scene: ap.a, model_point: pa, model_direction: Seg::new(pa, pb).dir, weight: 1.0 },
                PointOnLine { scene: af.b, model_point: fa, model_direction: from.dir, weight: 1.0 },
                PointOnLine { scene: ap.b, model_point: pa, model_direction: Seg::new(pa, pb).dir, weight: 1.0 },
            ];
            let Some(t) = pose_from_lines(&dirs, &points) else { continue };
            let maps_onto_itself = model.lines.iter().all(|l| {
                let (ta, tb) = (t * l.a, t * l.b);
                model.lines.iter().any(|m| {
                    ((m.a - ta).norm() < 1e-5 && (m.b - tb).norm() < 1e-5)
                        || ((m.a - tb).norm() < 1e-5 && (m.b - ta).norm() < 1e-5)
                })
            });
            if maps_onto_itself {
                return true;
            }
        }
    }
    false
}

/// Finds the instances of `model` among `scene` lines (in the `cam` frame).
pub fn locate(
    model: &MatcherModel,
    scene: &[Seg],
    p: &MatchParams,
    image: Option<&crate::verify::ImageEvidence>,
) -> Vec<Located> {
    locate_from(model, scene, &scene_pairs(scene, p), p, image).found
}

/// What one model's search leaves: the instances found, and the last round's candidates that
/// had the 3D evidence but not the image evidence (parts of them may be hidden, see
/// [`locate_all`]), best supported first.
struct Search {
    found: Vec<Located>,
    doubtful: Vec<Candidate>,
}

/// [`locate`], with the scene's seed pairs given (every model's matcher searches the same).
fn locate_from(
    model: &MatcherModel,
    scene: &[Seg],
    pairs: &[ScenePair],
    p: &MatchParams,
    image: Option<&crate::verify::ImageEvidence>,
) -> Search {
    // Tabled once per model; a search with another number of focus lines tables its own.
    let tabled = model.views.get_or_init(|| (p.focus_lines, characteristic_views(model, p)));
    let own;
    let views = if tabled.0 == p.focus_lines {
        &tabled.1
    } else {
        own = characteristic_views(model, p);
        &own
    };
    let mut free = vec![true; scene.len()];
    let mut found = Vec::new();
    let mut seen = hypotheses(model, scene, pairs, views, p);
    let mut doubtful = Vec::new();
    for _ in 0..p.max_instances {
        if !found.is_empty() {
            seen = rescored(model, scene, &free, &seen, p);
        }
        // The best-supported hypotheses, each refined and checked against the image, are
        // verified in order of both kinds of evidence; the first that passes is the next instance.
        // Those short of the 3D evidence or the image evidence needed are left out (their image
        // support is not worked out, or not to the end: the check stops once it must fail).
        doubtful.clear();
        let best = best_of(&seen)
            .into_iter()
            .filter_map(|start| {
                let (pose, score, pairs) = refine(model, scene, &free, start, p);
                let lines_seen = model_lines_of(&pairs).len();
                if score / model.total_length < p.min_support_fraction || lines_seen < p.min_support_lines {
                    return None;
                }
                let min_image = image_support_needed(lines_seen, p);
                let image_support = match image {
                    Some(ev) => match crate::verify::image_support_at_least(model, &pose, ev, min_image) {
                        Some(s) if s >= min_image => s,
                        _ => {
                            doubtful.push(Candidate { pose, score, pairs, image_support: 0.0 });
                            return None;
                        }
                    },
                    None => 1.0,
                };
                Some(Candidate { pose, score, pairs, image_support })
            })
            // The first of the highest rank.
            .min_by(|a, b| b.rank().total_cmp(&a.rank()));
        let Some(c) = best else { break };
        // The pose of the one that passes is refined on the image as well: 3D lines alone
        // leave flat parts a few degrees off.
        let c = match image {
            Some(ev) => in_image(model, scene, &free, c, p, ev),
            None => c,
        };
        let located = c.located(model, c.image_support);
        for &j in &located.scene_lines {
            free[j] = false;
        }
        found.push(located);
        doubtful.clear();
    }
    doubtful.sort_by(|a, b| b.score.total_cmp(&a.score));
    Search { found, doubtful }
}

/// The image support a candidate seen along `lines` model lines needs: the fewer the lines, the
/// more the image must bear it out (as in the second look: one line 85%, two 70%).
fn image_support_needed(lines: usize, p: &MatchParams) -> f64 {
    if lines <= p.min_support_lines { p.min_image_support.max(FEWEST_LINES_IMAGE_SUPPORT) } else { p.min_image_support }
}

/// The image support a candidate along no more than `min_support_lines` model lines needs.
/// Over 190 scenes 0.6 and 0.7 changed one scene alike (seed 90: a wedge read onto a block's
/// three lines, image 0.56, gone; the block found instead). Counting 4 lines as few too cost an
/// object and a false report on each of seeds 1-50 and 111-150 for two of each on 81-110.
const FEWEST_LINES_IMAGE_SUPPORT: f64 = 0.6;

/// The image-refined pose stands if it keeps this share of the candidate's rank: it is the
/// better estimate (50 scenes: 0.28 -> 0.19 mm and 0.74 -> 0.33 deg median, and one L-bracket
/// 6 deg off came within 5) even where a 3D line or two no longer quite lies along it. 0.9
/// added false reports on seeds 81-110; 1.0 kept the worse poses.
const KEEP_REFINED_RANK: f64 = 0.95;

/// The candidate refined on the image as well, if that keeps its rank (see [`KEEP_REFINED_RANK`]).
fn in_image(
    model: &MatcherModel,
    scene: &[Seg],
    free: &[bool],
    c: Candidate,
    p: &MatchParams,
    ev: &crate::verify::ImageEvidence,
) -> Candidate {
    let lines: Vec<(usize, usize)> = c.pairs.iter().map(|&(i, j, _)| (i, j)).collect();
    let Some(pose) = crate::image_fit::refine_in_image(model, &c.pose, scene, &lines, ev, crate::image_fit::SEARCH_PX)
    else {
        return c;
    };
    let (score, pairs) = support(model, &pose, scene, free, p);
    let image_support = crate::verify::image_support(model, &pose, ev);
    let refined = Candidate { pose, score, pairs, image_support };
    if refined.rank() >= KEEP_REFINED_RANK * c.rank() { refined } else { c }
}

/// A refined hypothesis with its evidence.
struct Candidate {
    pose: Isometry3<f64>,
    score: f64,
    pairs: Vec<(usize, usize, f64)>,
    image_support: f64,
}

impl Candidate {
    /// The candidate reported as an instance of `model`, with its image support.
    fn located(&self, model: &MatcherModel, image_support: f64) -> Located {
        let used = scene_lines_of(&self.pairs);
        Located {
            model: model.name.clone(),
            cam_from_model: self.pose,
            support: self.score,
            support_fraction: self.score / model.total_length,
            scene_lines: used,
            image_support,
            grasps: model.grasps.iter().map(|(g, w)| (self.pose * g, *w)).collect(),
        }
    }

    /// Matched 3D length weighted by how much of the pose's camera-facing wireframe the image
    /// shows.
    fn rank(&self) -> f64 {
        self.score * self.image_support
    }
}

/// Every model sought in the scene, each by its own matcher (in parallel, as MARVIN gave each
/// model a virtual matcher of its own); where two reports explain mostly the same scene lines,
/// the better supported one stands.
pub fn locate_all(
    models: &[MatcherModel],
    scene: &[Seg],
    p: &MatchParams,
    image: Option<&crate::verify::ImageEvidence>,
) -> Vec<Located> {
    use rayon::prelude::*;
    let pairs = scene_pairs(scene, p);
    let mut searches: Vec<Search> = models.par_iter().map(|m| locate_from(m, scene, &pairs, p, image)).collect();
    let mut kept = Vec::new();
    let mut claimed = vec![false; scene.len()];
    let all = searches.iter_mut().flat_map(|s| std::mem::take(&mut s.found)).collect();
    resolve(models, all, &mut kept, &mut claimed);
    if let Some(ev) = image.filter(|ev| !ev.lines.is_empty()) {
        let (solids, explained) = (solids_of(models, &kept), explained_by(models, &kept, ev));
        let second: Vec<Located> = models
            .par_iter()
            .flat_map(|m| crate::second_look::locate(m, scene, &claimed, p, ev, (&solids, &explained)))
            .collect();
        resolve(models, second, &mut kept, &mut claimed);
    }
    if let Some(ev) = image {
        let third = hidden_in_part(models, &searches, (&kept, &claimed), p, ev);
        resolve(models, third, &mut kept, &mut claimed);
    }
    kept
}

/// The image edges of the objects located.
fn explained_by(
    models: &[MatcherModel],
    kept: &[Located],
    ev: &crate::verify::ImageEvidence,
) -> crate::verify::Explained {
    let located = kept.iter().filter_map(|l| Some((models.iter().find(|m| m.name == l.model)?, &l.cam_from_model)));
    crate::verify::Explained::of(located, ev.cam)
}

/// The objects located, as solids that may hide other objects' parts.
fn solids_of(models: &[MatcherModel], kept: &[Located]) -> Vec<crate::occlusion::Solid> {
    kept.iter()
        .filter_map(|l| {
            let model = models.iter().find(|m| m.name == l.model)?;
            Some(crate::occlusion::Solid::new(model, &l.cam_from_model))
        })
        .collect()
}

/// Candidates that had the 3D evidence but too little of their wireframe ran along edgels,
/// checked again on the part of it that nothing hides: neither the objects located (wherever
/// they stand nearer the camera) nor the model's own bulk. A part lying partly behind another
/// can show only what is left in view, and a channel hides its own inner edges; counted as
/// unseen, those parts failed objects that were otherwise well supported (50 scenes: located
/// 0.942 -> 0.948, and one more object on each of seeds 51-80 and 81-110, with the same false
/// reports). At most one per model, the best supported that passes.
fn hidden_in_part(
    models: &[MatcherModel],
    searches: &[Search],
    (kept, claimed): (&[Located], &[bool]),
    p: &MatchParams,
    ev: &crate::verify::ImageEvidence,
) -> Vec<Located> {
    let (solids, explained) = (solids_of(models, kept), explained_by(models, kept, ev));
    let mut out = Vec::new();
    for (model, search) in models.iter().zip(searches) {
        for c in &search.doubtful {
            // Cheap tests first: lines another object explains, or space another fills.
            let mut loc = c.located(model, 0.0);
            if !admissible(models, &loc, kept, claimed) {
                continue;
            }
            let own = crate::occlusion::Solid::new(model, &c.pose);
            let hiding: Vec<&crate::occlusion::Solid> = solids.iter().chain([&own]).collect();
            let (image_support, unhidden) = crate::verify::image_support_unhidden(model, &c.pose, ev, &hiding);
            if image_support >= p.min_image_support
                && unhidden >= crate::occlusion::MIN_IN_VIEW
                && explained.share(model, &c.pose, ev.cam) <= crate::verify::MAX_EXPLAINED
            {
                loc.image_support = image_support;
                out.push(loc);
                break;
            }
        }
    }
    out
}

/// Adds `reports` to `kept`, best first, unless one reuses over 30% of lines already claimed or
/// fills space a kept object fills; claims the lines of those it keeps.
fn resolve(models: &[MatcherModel], mut reports: Vec<Located>, kept: &mut Vec<Located>, claimed: &mut [bool]) {
    let score = |l: &Located| l.support * l.image_support;
    reports.sort_by(|a, b| score(b).total_cmp(&score(a)));
    for loc in reports {
        if !admissible(models, &loc, kept, claimed) {
            continue;
        }
        for &j in &loc.scene_lines {
            claimed[j] = true;
        }
        kept.push(loc);
    }
}

/// Whether a report may join those `kept`: no more than 30% of its lines `claimed` by them (else
/// its evidence is another object's), and sharing little space with any of them (solids cannot).
/// Space is judged on the solids themselves, not on spheres round them: a part nestled in a
/// U-channel's mouth lies near the channel's centre but fills none of its space (judged by
/// centres, a T-piece found at 0.2 mm was turned away on seed 96).
fn admissible(models: &[MatcherModel], loc: &Located, kept: &[Located], claimed: &[bool]) -> bool {
    let shared = loc.scene_lines.iter().filter(|&&j| claimed[j]).count();
    if shared * 10 > loc.scene_lines.len() * 3 {
        return false;
    }
    let model_of = |name: &str| models.iter().find(|m| m.name == name);
    let Some(model) = model_of(&loc.model) else { return true };
    !kept.iter().any(|k| {
        model_of(&k.model).is_some_and(|other| {
            space_shared(model, &loc.cam_from_model, other, &k.cam_from_model) > MAX_SPACE_SHARED
                || space_shared(other, &k.cam_from_model, model, &loc.cam_from_model) > MAX_SPACE_SHARED
        })
    })
}

/// Two objects cannot fill the same space: a report sharing more than this fraction of its own
/// interior, or of a kept object's, with that object is not admissible. Poses a millimetre off
/// share a sliver where solids touch; a second report of one object shares nearly all.
const MAX_SPACE_SHARED: f64 = 0.2;

/// The fraction of `a`'s interior points (at `a_pose`) that lie inside `b` (at `b_pose`).
fn space_shared(a: &MatcherModel, a_pose: &Isometry3<f64>, b: &MatcherModel, b_pose: &Isometry3<f64>) -> f64 {
    let ((ca, ra), (cb, rb)) = (a.bounding_sphere(), b.bounding_sphere());
    if (a_pose * ca - b_pose * cb).norm() > ra + rb || a.interior.is_empty() {
        return 0.0;
    }
    let b_from_a = b_pose.inverse() * a_pose;
    let (lo, hi) = b.bounds;
    let inside = a
        .interior
        .iter()
        .map(|p| b_from_a * p)
        .filter(|p| (0..3).all(|k| (lo[k]..=hi[k]).contains(&p[k])) && mesh::trimesh::encloses(&b.triangles, p))
        .count();
    inside as f64 / a.interior.len() as f64
}

/// The hypotheses that congruent scene pairs (of `pairs`, all of free lines) give and that find
/// at least the support a located object needs (`min_support_fraction` of the wireframe) and
/// make the search's best so far (see [`Seen`]), with that support.
fn hypotheses(
    model: &MatcherModel,
    scene: &[Seg],
    pairs: &[ScenePair],
    views: &[Vec<FocusPair>],
    p: &MatchParams,
) -> Vec<(f64, Isometry3<f64>)> {
    use rayon::prelude::*;
    let free_lines = FreeLines::new(scene, &vec![true; scene.len()]);
    // One subordinate matcher per characteristic view, in parallel.
    views
        .par_iter()
        .flat_map_iter(|focus| {
            let mut seen = Seen::new(p.min_support_fraction * model.total_length);
            for_each_hypothesis(model, scene, (pairs, &free_lines), focus, p, &mut seen);
            seen.all
        })
        .collect()
}

/// The hypotheses of an earlier search with their support among the lines still free, those
/// that still find enough. A later search for another instance would find no others: its
/// scene pairs are among the earlier ones, giving the same poses, and support only shrinks as
/// lines are claimed. (Searching again took half the matcher's time.)
fn rescored(
    model: &MatcherModel,
    scene: &[Seg],
    free: &[bool],
    earlier: &[(f64, Isometry3<f64>)],
    p: &MatchParams,
) -> Vec<(f64, Isometry3<f64>)> {
    let free_lines = FreeLines::new(scene, free);
    let floor = p.min_support_fraction * model.total_length;
    let mut near = NearLines::default();
    earlier
        .iter()
        .filter_map(|(_, pose)| {
            support_score(model, pose, scene, &free_lines, p, floor, &mut near).map(|score| (score, *pose))
        })
        .collect()
}

/// The best-supported poses (up to `HYPOTHESES`, no two alike), best first.
fn best_of(hypotheses: &[(f64, Isometry3<f64>)]) -> Vec<Isometry3<f64>> {
    let mut best = Vec::new();
    for &(score, pose) in hypotheses {
        keep_best(&mut best, score, pose);
    }
    best.into_iter().map(|(_, pose)| pose).collect()
}

/// The hypotheses of a search that find support above `floor` and, once [`RECORDED`] have,
/// above the least of the best [`RECORDED`] so far (a hypothesis that cannot make those is
/// neither this search's best nor, once lines are claimed, a later one's).
struct Seen {
    floor: f64,
    all: Vec<(f64, Isometry3<f64>)>,
    /// The best scores so far, least on top.
    best: std::collections::BinaryHeap<std::cmp::Reverse<Score>>,
}

/// Hypotheses whose support sets the floor of a search. 60 found slightly more objects than
/// keeping every hypothesis over the minimum support, with 5% less work; 30 found fewer.
const RECORDED: usize = 60;

/// A support score, ordered.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Score(f64);

impl Eq for Score {}

impl PartialOrd for Score {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Score {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

impl Seen {
    fn new(floor: f64) -> Seen {
        Seen { floor, all: Vec::new(), best: std::collections::BinaryHeap::new() }
    }

    /// The support a hypothesis must exceed to be recorded.
    fn floor(&self) -> f64 {
        match self.best.peek() {
            Some(std::cmp::Reverse(Score(least))) if self.best.len() == RECORDED => self.floor.max(*least),
            _ => self.floor,
        }
    }

    fn record(&mut self, score: f64, pose: Isometry3<f64>) {
        self.all.push((score, pose));
        self.best.push(std::cmp::Reverse(Score(score)));
        if self.best.len() > RECORDED {
            self.best.pop();
        }
    }
}

/// Two free scene lines that could seed a hypothesis, with their relations.
struct ScenePair {
    j: usize,
    l: usize,
    angle: f64,
    separation: f64,
    /// Where the closest approach falls along each, from its start.
    at_j: f64,
    at_l: f64,
}

/// Every ordered pair of scene lines long enough to seed and far enough from parallel.
fn scene_pairs(scene: &[Seg], p: &MatchParams) -> Vec<ScenePair> {
    let seeds: Vec<usize> = (0..scene.len()).filter(|&j| scene[j].len >= p.min_seed_length).collect();
    let mut out = Vec::new();
    for &j in &seeds {
        for &l in &seeds {
            let (sj, sl) = (&scene[j], &scene[l]);
            let angle = line_angle(&sj.dir, &sl.dir);
            if j == l || angle < 0.3 {
                continue;
            }
            let separation = separation(&sj.a, &sj.dir, &sl.a, &sl.dir);
            let (at_j, at_l) = closest_params(&sj.a, &sj.dir, &sl.a, &sl.dir);
            out.push(ScenePair { j, l, angle, separation, at_j, at_l });
        }
    }
    out
}

/// Hands `sink` each hypothesis from a scene pair congruent with a focus pair, with its support
/// (those that cannot beat the sink's floor are left unscored and unseen).
fn for_each_hypothesis(
    model: &MatcherModel,
    scene: &[Seg],
    (pairs, free_lines): (&[ScenePair], &FreeLines),
    focus: &[FocusPair],
    p: &MatchParams,
    sink: &mut Seen,
) {
    let mut near = NearLines::default();
    for sp in pairs {
        let (sj, sl) = (&scene[sp.j], &scene[sp.l]);
        let (tj, tl) = (sp.at_j, sp.at_l);
        {
            let from = focus.partition_point(|f| f.separation < sp.separation - p.separation_tolerance);
            let within = focus[from..].iter().take_while(|f| f.separation <= sp.separation + p.separation_tolerance);
            for f in within {
                if (sp.angle - f.angle).abs() > p.angle_tolerance {
                    continue;
                }
                let (mi, mk) = (&model.lines[f.focus], &model.lines[f.partner]);
                // Each fragment must fit along its model line with the closest approach where the
                // model has it (with slack for the ends stereo loses); that fixes which way round
                // each scene line runs, and the model pair's cosine sign must agree.
                let slack = FIT_SLACK * p.support_distance;
                let cos = mi.dir.dot(&mk.dir);
                for (sign_j, sign_l) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                    let tj_from_start = if sign_j > 0.0 { tj } else { sj.len - tj };
                    if !fits_along(tj_from_start, sj.len, f.at_focus, mi.len, slack) {
                        continue;
                    }
                    let vj = sj.dir * sign_j;
                    // The cosine's sign must agree, unless the lines are too near perpendicular
                    // for it to say anything: then both ways round are tried (taking the noise's
                    // word for it lost one of a rectangle's two readings, and with it many
                    // objects, which came out turned over).
                    let scene_cos = vj.dot(&sl.dir) * sign_l;
                    if cos.abs() > PERPENDICULAR_COS && (scene_cos >= 0.0) != (cos >= 0.0) {
                        continue;
                    }
                    let tl_from_start = if sign_l > 0.0 { tl } else { sl.len - tl };
                    if !fits_along(tl_from_start, sl.len, f.at_partner, mk.len, slack) {
                        continue;
                    }
                    let vl = sl.dir * sign_l;
                    let Some(rotation) = rotation_from_two_directions([mi.dir, mk.dir], [vj, vl]) else { continue };
                    let on = |x: Point3<f64>, m: &Seg| PointOnLine {
                        scene: x,
                        model_point: m.a,
                        model_direction: m.dir,
                        weight: 1.0,
                    };
                    let points = [on(sj.a, mi), on(sj.b, mi), on(sl.a, mk), on(sl.b, mk)];
                    let Some(t) = translation_from_points(&rotation, &points) else { continue };
                    let pose = Isometry3::from_parts(t.into(), rotation);
                    if let Some(score) = support_score(model, &pose, scene, free_lines, p, sink.floor(), &mut near) {
                        sink.record(score, pose);
                    }
                }
            }
        }
    }
}

/// A fragment's closest approach to its partner may fall this many support distances beyond
/// where the model has it (stereo loses line ends near corners). 4 found the same objects as 3
/// from 12% more hypotheses; 2 lost some.
const FIT_SLACK: f64 = 3.0;

/// Two lines whose directions' cosine is smaller than this are taken as perpendicular: the sign
/// of a scene pair's cosine then says nothing (noise of the angle tolerance's size decides it).
const PERPENDICULAR_COS: f64 = 0.1;

/// Hypotheses kept for verification per search.
const HYPOTHESES: usize = 12;

/// Keeps the `HYPOTHESES` best-scored poses, a pose near a kept one (within 5 mm and 5 deg)
/// replacing it only if it scores better.
fn keep_best(best: &mut Vec<(f64, Isometry3<f64>)>, score: f64, pose: Isometry3<f64>) {
    if best.len() == HYPOTHESES && best.last().is_some_and(|(s, _)| score <= *s) {
        return;
    }
    let alike = |q: &Isometry3<f64>| {
        (q.translation.vector - pose.translation.vector).norm() < 0.005 && q.rotation.angle_to(&pose.rotation) < 0.087
    };
    if let Some(k) = best.iter().position(|(_, q)| alike(q)) {
        if best[k].0 >= score {
            return;
        }
        best.remove(k);
    }
    let at = best.iter().position(|(s, _)| *s < score).unwrap_or(best.len());
    best.insert(at, (score, pose));
    best.truncate(HYPOTHESES);
}

/// Refits a pose on its supporting correspondences until the support stops growing.
fn refine(
    model: &MatcherModel,
    scene: &[Seg],
    free: &[bool],
    mut pose: Isometry3<f64>,
    p: &MatchParams,
) -> (Isometry3<f64>, f64, Vec<(usize, usize, f64)>) {
    let (mut score, mut pairs) = support(model, &pose, scene, free, p);
    for _ in 0..5 {
        let Some(next) = fit(model, scene, &pairs, &pose) else { break };
        let (s, pr) = support(model, &next, scene, free, p);
        if s + 1e-9 < score {
            break;
        }
        // The same correspondences give the same fit: once they stop changing, it has settled.
        let settled = pr.len() == pairs.len() && pr.iter().zip(&pairs).all(|(a, b)| a.0 == b.0 && a.1 == b.1);
        (pose, score, pairs) = (next, s, pr);
        if settled {
            break;
        }
    }
    (pose, score, pairs)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn widget() -> MatcherModel {
        crate::fixtures::model("widget")
    }

    /// A tiny deterministic generator, so the test needs no RNG crate.
    pub(crate) struct Lcg(pub u64);
    impl Lcg {
        pub(crate) fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        pub(crate) fn noise(&mut self, s: f64) -> Vector3<f64> {
            Vector3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5) * 2.0 * s
        }
    }

    /// The model's lines in the scene: half of them hidden, the rest cut to fragments, their ends
    /// noised, some reversed, and random distractors added.
    fn scene_of(model: &MatcherModel, pose: &Isometry3<f64>, rng: &mut Lcg) -> Vec<Seg> {
        let mut scene = Vec::new();
        for (k, l) in model.lines.iter().enumerate() {
            if k % 2 == 1 {
                continue; // hidden
            }
            let t = l.transformed(pose);
            let (s0, s1) = (0.1 * rng.next(), 0.75 + 0.2 * rng.next());
            let (a, b) = (t.a + (t.b - t.a) * s0 + rng.noise(2e-4), t.a + (t.b - t.a) * s1 + rng.noise(2e-4));
            scene.push(if k % 3 == 0 { Seg::new(b, a) } else { Seg::new(a, b) });
        }
        for _ in 0..15 {
            let a = Point3::from(pose.translation.vector + rng.noise(0.15));
            scene.push(Seg::new(a, a + rng.noise(0.04)));
        }
        scene
    }

    #[test]
    fn the_pose_comes_back_within_the_noise() {
        let model = widget();
        let mut rng = Lcg(7);
        for (k, rpy) in [(0.0, 0.0, 0.3), (1.57, 0.0, -0.8), (0.4, 2.1, 1.0)].iter().enumerate() {
            let pose = Isometry3::from_parts(
                Translation3::new(0.03, -0.05, 0.85),
                UnitQuaternion::from_euler_angles(rpy.0, rpy.1, rpy.2),
            );
            let scene = scene_of(&model, &pose, &mut rng);
            let found = locate(&model, &scene, &MatchParams::default(), None);
            assert!(!found.is_empty(), "case {k}: not found");
            let got = &found[0].cam_from_model;
            let pos_err = (got.translation.vector - pose.translation.vector).norm();
            let rot_err = got.rotation.angle_to(&pose.rotation);
            assert!(pos_err < 1e-3, "case {k}: {:.2} mm off", pos_err * 1e3);
            assert!(rot_err < 0.5f64.to_radians(), "case {k}: {:.2} deg off", rot_err.to_degrees());
            assert_eq!(found.len(), 1, "case {k}: a second, false instance");
            // The grasp comes out in the camera frame, where the model's pose puts it.
            let (cam_from_gripper, width) = found[0].grasps[0];
            let expect = pose * model.grasps[0].0;
            assert!((cam_from_gripper.translation.vector - expect.translation.vector).norm() < 1e-3);
            assert_eq!(width, model.grasps[0].1);
        }
    }

    /// The L-bracket's four longest edges all run along its length; its focus lines must not,
    /// or an L-bracket whose length lies along the rasters could not be seeded.
    #[test]
    fn focus_lines_run_in_every_direction_the_model_has() {
        let model = crate::fixtures::model("l_bracket");
        let all: Vec<usize> = (0..model.lines.len()).collect();
        let focus = focus_lines(&model, &all, 4);
        assert_eq!(focus.len(), 4);
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            assert!(
                focus.iter().any(|&i| line_angle(&model.lines[i].dir, &axis) < 0.1),
                "no focus line along {axis:?}: {focus:?}"
            );
        }
        // The longest line of each direction comes first: the 70 mm edge, then the 50 mm one.
        assert_eq!(model.lines[focus[0]].len, model.lines.iter().map(|l| l.len).fold(0.0, f64::max));
        assert!((model.lines[focus[1]].len - 0.05).abs() < 1e-9);
    }

    #[test]
    fn a_scene_of_distractors_alone_yields_nothing() {
        let model = widget();
        let mut rng = Lcg(3);
        let scene: Vec<Seg> = (0..40)
            .map(|_| {
                let a = Point3::new(0.0, 0.0, 0.9) + rng.noise(0.15);
                Seg::new(a, a + rng.noise(0.05))
            })
            .collect();
        assert!(locate(&model, &scene, &MatchParams::default(), None).is_empty());
    }

    /// A symmetric model seen from above: only the lines on faces turned towards a camera over
    /// it (the top and the sides), fragmented and noised. The pose comes back up to the model's
    /// symmetry, although its equivalent focus pairs are tabled once.
    #[test]
    fn a_symmetric_model_seen_from_one_side_is_found_up_to_its_symmetry() {
        let lib = mesh::Library::load_default().unwrap();
        for name in ["block", "hex_prism"] {
            let model = MatcherModel::from_model(lib.get(name).unwrap());
            let pose = Isometry3::from_parts(
                Translation3::new(-0.02, 0.04, 0.9),
                UnitQuaternion::from_euler_angles(2.6, 0.3, -0.7),
            );
            let mut rng = Lcg(11);
            let scene: Vec<Seg> = (0..model.lines.len())
                .filter(|&k| model.faces_camera(k, &pose))
                .map(|k| {
                    let t = model.lines[k].transformed(&pose);
                    Seg::new(t.a + (t.b - t.a) * 0.05 + rng.noise(2e-4), t.a + (t.b - t.a) * 0.9 + rng.noise(2e-4))
                })
                .collect();
            let found = locate(&model, &scene, &MatchParams::default(), None);
            assert_eq!(found.len(), 1, "{name}");
            // Equivalent under the symmetry: every model line lands on a model line of the truth.
            let got = found[0].cam_from_model;
            for l in &model.lines {
                let (a, b) = (got * l.a, got * l.b);
                let on_truth = model.lines.iter().any(|m| {
                    let (ma, mb) = (pose * m.a, pose * m.b);
                    ((ma - a).norm() < 2e-3 && (mb - b).norm() < 2e-3)
                        || ((ma - b).norm() < 2e-3 && (mb - a).norm() < 2e-3)
                });
                assert!(on_truth, "{name}: a line of the located model is not on the true one");
            }
        }
    }

    /// Solids may not share space: the same block a millimetre off shares nearly all of it, a
    /// block beside it none, and a T-piece whose stem stands in a U-channel's mouth none either,
    /// though their centres nearly coincide (as they would for one object inside another).
    #[test]
    fn reports_may_not_fill_the_same_space() {
        let (block, channel, tee) =
            (crate::fixtures::model("block"), crate::fixtures::model("u_channel"), crate::fixtures::model("t_piece"));
        let at = |x: f64, y: f64| Isometry3::translation(x, y, 0.8);
        assert!(space_shared(&block, &at(0.0, 0.0), &block, &at(0.001, 0.0)) > 0.9);
        assert_eq!(space_shared(&block, &at(0.0, 0.0), &block, &at(0.061, 0.0)), 0.0);
        // The channel's mouth spans x -25..25 mm, y -10..25 mm; the tee's stem x -10..10 mm,
        // y -30..10 mm, so 20.5 mm up it stands in the mouth, its bar above the channel's arms.
        let (c, t) = (at(0.0, 0.0), at(0.0, 0.0205));
        assert_eq!(space_shared(&tee, &t, &channel, &c), 0.0);
        assert_eq!(space_shared(&channel, &c, &tee, &t), 0.0);
        assert!(space_shared(&tee, &at(0.0, 0.0), &channel, &c) > 0.2, "the tee 20 mm lower cuts into the channel");
        let ((cc, cr), (tc, tr)) = (channel.bounding_sphere(), tee.bounding_sphere());
        assert!((c * cc - t * tc).norm() < 0.3 * (cr + tr));
    }
}
