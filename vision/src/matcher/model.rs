//! The model as the matcher holds it, and what every matcher stage shares: straight 3D
//! segments and their pairwise relations, the model's wireframe with the faces along each line,
//! its solid and grasps, the tables derived from it once (its characteristic views' focus
//! pairs, the grid of lines near each cell), the matcher's parameters, and a located object.

use nalgebra::{Isometry3, Point3, Rotation3, Vector3};
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

/// A model as the matcher sees it: its wireframe and its markings (a pattern's lines).
#[derive(Debug, Clone)]
pub struct MatcherModel {
    pub name: String,
    pub lines: Vec<Seg>,
    /// `lines[first_marking..]` are the markings (a pattern drawn on a face), the others the
    /// wireframe's edges.
    pub(crate) first_marking: usize,
    /// Outward normals of the faces meeting along each line: the line can be seen only from
    /// where one of them faces the camera.
    pub faces: Vec<Vec<Vector3<f64>>>,
    /// Per line, each face along it and where it lies beside the line: where the image shows
    /// that face beside the line's edge.
    pub(crate) face_sides: Vec<Vec<FaceSide>>,
    /// Whether the solid is convex, and so hides none of its own surface from a camera.
    pub(crate) convex: bool,
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
    pub(crate) views: std::sync::OnceLock<(usize, Vec<Vec<FocusPair>>)>,
    /// The lines near each cell of a grid over the model, laid out on the first search for its
    /// support distance (kept with it).
    pub(crate) grid: std::sync::OnceLock<LineGrid>,
    /// The corners as the part lying flat shows them, on the first image look for the table's
    /// normal then (`cam`), kept with it.
    pub(crate) flat_corners: std::sync::OnceLock<(Vector3<f64>, FlatCorners)>,
    /// The half turns (model frame) that carry the part most nearly onto itself, worked out on
    /// first use ([`super::turns::of`]).
    pub(crate) turns: std::sync::OnceLock<Vec<Isometry3<f64>>>,
    /// Those and the half turns of a slab of the part on itself, which only both images tell
    /// from the report ([`super::turns::in_stereo`]), worked out on first use.
    pub(crate) stereo_turns: std::sync::OnceLock<Vec<Isometry3<f64>>>,
    /// The outward normals of the faces the part can lie on (those of its convex hull's facets
    /// that are faces of the solid), model frame: a part lying flat on the table has one of
    /// them pointing straight down.
    pub(crate) resting: Vec<Vector3<f64>>,
    /// The lines' ends, each once (model frame).
    pub(crate) corners: Vec<Point3<f64>>,
    /// Every two lines leaving one corner at an angle, both ways round: where the second look
    /// and the image look put a model corner on an image's.
    pub(crate) corner_edges: Vec<Corner>,
}

impl MatcherModel {
    pub fn from_model(m: &mesh::Model) -> MatcherModel {
        // A pattern's lines (the flag's checker) are seen as edges too.
        let lines: Vec<Seg> = m.wireframe.iter().chain(&m.markings).map(|s| Seg::new(s.a, s.b)).collect();
        let faces: Vec<Vec<Vector3<f64>>> = lines.iter().map(|l| faces_along(&m.mesh, l)).collect();
        let n = (2 * lines.len()).max(1) as f64;
        let centre = Point3::from(lines.iter().map(|l| l.a.coords + l.b.coords).sum::<Vector3<f64>>() / n);
        let radius = lines.iter().flat_map(|l| [l.a, l.b]).map(|p| (p - centre).norm()).fold(0.0, f64::max);
        let mut longest_first: Vec<usize> = (0..lines.len()).collect();
        longest_first.sort_by(|&a, &b| lines[b].len.total_cmp(&lines[a].len));
        let triangles: Vec<[Point3<f64>; 3]> = (0..m.mesh.triangles.len()).map(|t| m.mesh.corners(t)).collect();
        let bounds = m.mesh.bounds().unwrap_or((Point3::origin(), Point3::origin()));
        let face_sides = lines.iter().zip(&faces).map(|(l, n)| face_sides(l, n, &triangles)).collect();
        MatcherModel {
            resting: resting_normals(&triangles),
            corners: distinct_ends(&lines),
            corner_edges: corner_edges(&lines),
            face_sides,
            convex: is_convex(&triangles),
            interior: interior_points(bounds, &triangles),
            bounds,
            sphere: (centre, radius),
            longest_first,
            name: m.name.clone(),
            faces,
            triangles,
            total_length: lines.iter().map(|l| l.len).sum(),
            first_marking: m.wireframe.len(),
            grasps: m.grasps.iter().map(|g| (g.model_from_gripper, g.opening)).collect(),
            lines,
            views: std::sync::OnceLock::new(),
            grid: std::sync::OnceLock::new(),
            flat_corners: std::sync::OnceLock::new(),
            turns: std::sync::OnceLock::new(),
            stereo_turns: std::sync::OnceLock::new(),
        }
    }
}

/// Two model edges leaving one corner: `corner` and the unit directions out of it.
#[derive(Debug, Clone)]
pub(crate) struct Corner {
    pub(crate) line: usize,
    pub(crate) other: usize,
    pub(crate) corner: Point3<f64>,
    pub(crate) out: Vector3<f64>,
    pub(crate) other_out: Vector3<f64>,
    pub(crate) other_len: f64,
}

/// A model corner as a part lying flat on its face `resting` (outward normal, model frame)
/// shows it (for the image look, [`super::image_look`]), in `cam`'s axes before the turn about the table's normal that places it: the
/// turn `lay` that rests the face on the table, the corner's level edge leaving it along
/// `out`, the other edge, and the corner's height above the top; where the other
/// edge is level too, the cosine and sine of the turn about the table's normal from the one to
/// the other (which no turn about the normal changes).
#[derive(Debug, Clone)]
pub(crate) struct FlatCorner {
    pub(crate) corner: Corner,
    pub(crate) lay: Rotation3<f64>,
    pub(crate) out: Vector3<f64>,
    pub(crate) out_len: f64,
    pub(crate) height: f64,
    pub(crate) level_turn: Option<(f64, f64)>,
    /// Whether the other edge runs straight up (1) or down (-1) from the corner, if it does.
    pub(crate) upright: Option<f64>,
    /// The other edge in the level edge's frame: along `out`, along the table's normal crossed
    /// with `out`, and along the normal. With the height and the two edges' lengths, all that
    /// decides whether the corner fits an image corner (only the pose depends on the rest).
    pub(crate) other_local: Vector3<f64>,
    /// Which of the model's corner shapes it has: flat corners of one shape fit the same image
    /// corners, where their corners lie on the same rays ([`FlatCorners::shapes`]).
    pub(crate) shape: usize,
}

/// A model's flat corners with an index by what the other edge does: lying level (by the
/// angle they make on the table), standing upright (up, down), or neither; so that an image
/// corner is tried only against those that may fit it (most of the image look's time went on
/// trying every corner against every image corner).
#[derive(Debug, Clone)]
pub(crate) struct FlatCorners {
    pub(crate) all: Vec<FlatCorner>,
    /// Level ones by the angle from the level edge to the other, ascending.
    pub(crate) level: Vec<(f64, usize)>,
    pub(crate) upright: [Vec<usize>; 2],
    pub(crate) other: Vec<usize>,
    /// How many distinct shapes the corners have (boxes' corners are mostly alike: a block lying
    /// on a face has four corners of each of a few shapes).
    pub(crate) shapes: usize,
}

/// Every two edges of `lines` that leave one corner at an angle, both ways round.
fn corner_edges(lines: &[Seg]) -> Vec<Corner> {
    let mut out = Vec::new();
    for (i, li) in lines.iter().enumerate() {
        for (k, lk) in lines.iter().enumerate() {
            if i == k || line_angle(&li.dir, &lk.dir) < 0.35 {
                continue;
            }
            for (ci, ei) in [(li.a, li.b), (li.b, li.a)] {
                for (ck, ek) in [(lk.a, lk.b), (lk.b, lk.a)] {
                    if (ci - ck).norm() < 1e-6 {
                        out.push(Corner {
                            line: i,
                            other: k,
                            corner: ci,
                            out: (ei - ci).normalize(),
                            other_out: (ek - ck).normalize(),
                            other_len: lk.len,
                        });
                    }
                }
            }
        }
    }
    out
}

/// The ends of `lines`, each once.
fn distinct_ends(lines: &[Seg]) -> Vec<Point3<f64>> {
    let mut out: Vec<Point3<f64>> = Vec::new();
    for c in lines.iter().flat_map(|l| [l.a, l.b]) {
        if !out.iter().any(|o| (o - c).norm() < 1e-9) {
            out.push(c);
        }
    }
    out
}

/// The outward normals of the faces of `triangles` that lie on the solid's convex hull (no
/// corner beyond their plane), each once.
fn resting_normals(triangles: &[[Point3<f64>; 3]]) -> Vec<Vector3<f64>> {
    let mut out: Vec<Vector3<f64>> = Vec::new();
    for t in triangles {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        if n.norm() < 1e-12 {
            continue;
        }
        let n = n.normalize();
        let on_hull = triangles.iter().flatten().all(|c| (c - t[0]).dot(&n) <= 1e-7);
        if on_hull && !out.iter().any(|o| (o - n).norm() < 1e-6) {
            out.push(n);
        }
    }
    out
}

/// A face along a line: its outward normal, the unit vector from the line into the face
/// (perpendicular to the line), and how far the face reaches that way (metres).
pub(crate) type FaceSide = (Vector3<f64>, Vector3<f64>, f64);

/// For each face along `line` (of outward `normals`) of the surface `triangles`: its normal,
/// the unit vector from the line into the face, perpendicular to the line, and how far the face
/// reaches that way (metres).
fn face_sides(line: &Seg, normals: &[Vector3<f64>], triangles: &[[Point3<f64>; 3]]) -> Vec<FaceSide> {
    let off_line = |p: &Point3<f64>| {
        let w = p - line.a;
        w - line.dir * w.dot(&line.dir)
    };
    let normal_of = |t: &[Point3<f64>; 3]| {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        (n.norm() > 1e-12).then(|| n.normalize())
    };
    let mut out = Vec::new();
    for n in normals {
        let in_face = |t: &&[Point3<f64>; 3]| {
            normal_of(t).is_some_and(|tn| (tn - n).norm() < 1e-6) && (t[0] - line.a).dot(n).abs() < 1e-7
        };
        let side = triangles.iter().filter(in_face).find_map(|t| {
            let on: Vec<bool> = t.iter().map(|p| off_line(p).norm() < 1e-7).collect();
            if on.iter().filter(|o| **o).count() != 2 {
                return None;
            }
            let third = t.iter().zip(&on).find(|(_, o)| !**o)?.0;
            Some(off_line(third).normalize())
        });
        if let Some(side) = side {
            let reach = triangles.iter().filter(in_face).flatten().map(|p| (p - line.a).dot(&side)).fold(0.0, f64::max);
            out.push((*n, side, reach));
        }
    }
    out
}

/// Whether every corner of the surface `triangles` lies on or behind the plane of each of them.
fn is_convex(triangles: &[[Point3<f64>; 3]]) -> bool {
    triangles.iter().all(|t| {
        let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
        triangles.iter().flatten().all(|p| n.dot(&(p - t[0])) <= 1e-9)
    })
}

/// Spacing of the grid of points that fills a model (metres).
pub(crate) const INTERIOR_STEP: f64 = 0.004;

/// The points of a grid over a solid's bounds that lie inside its surface `triangles` (grid nodes fall half a step
/// in from the bounds, off the planes of the faces).
pub(crate) fn interior_points(
    (lo, hi): (Point3<f64>, Point3<f64>),
    triangles: &[[Point3<f64>; 3]],
) -> Vec<Point3<f64>> {
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
pub(crate) fn faces_along(mesh: &mesh::TriMesh, line: &Seg) -> Vec<Vector3<f64>> {
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

    /// Whether line `k` is a marking (drawn on a face, not an edge of the solid).
    pub fn is_marking(&self, k: usize) -> bool {
        k >= self.first_marking
    }

    /// Whether line `k` has a face turned towards a camera at the origin, with the model at
    /// `pose` (lines of no face always do): only such lines can be seen.
    pub fn faces_camera(&self, k: usize, pose: &Isometry3<f64>) -> bool {
        self.faces_eye(k, &eye_of(pose))
    }

    /// [`MatcherModel::faces_camera`] with the camera at `eye` in the model's frame ([`eye_of`]
    /// the pose): a loop over the lines carries the camera there once, not once a line.
    pub fn faces_eye(&self, k: usize, eye: &Point3<f64>) -> bool {
        let line = &self.lines[k];
        self.faces_towards(k, &(eye - nalgebra::center(&line.a, &line.b)), 0.0)
    }

    /// Whether line `k` may be what the camera sees from `eye` (the model's frame, see
    /// [`eye_of`]), with the model at a pose some degrees off: one of its faces turned towards
    /// the camera, or no further from it than [`SEEN_SLACK`] (the cosine of its normal with the
    /// line of sight). A hypothesis that puts a 3D line on an edge of the model's far side is no
    /// reading of it. (Tested in the model's frame: no normal need be carried into `cam`.)
    pub(crate) fn may_be_seen(&self, k: usize, eye: &Point3<f64>) -> bool {
        let line = &self.lines[k];
        self.may_be_seen_along(k, &(eye - nalgebra::center(&line.a, &line.b)))
    }

    /// [`Self::may_be_seen`], looking along `-towards` (the model's frame): from a point of
    /// the line to the camera.
    pub(crate) fn may_be_seen_along(&self, k: usize, towards: &Vector3<f64>) -> bool {
        self.faces_towards(k, towards, -SEEN_SLACK * towards.norm())
    }

    /// Whether line `k` has no face, or one whose normal dotted with `towards` (the model's
    /// frame) exceeds `least`.
    fn faces_towards(&self, k: usize, towards: &Vector3<f64>, least: f64) -> bool {
        self.faces[k].is_empty() || self.faces[k].iter().any(|n| n.dot(towards) > least)
    }

    /// The grasp positions in the `cam` frame with the model at `pose`: `cam_from_gripper` and
    /// the jaw opening (metres), as [`Located::grasps`] holds them.
    pub fn grasps_at(&self, pose: &Isometry3<f64>) -> Vec<(Isometry3<f64>, f64)> {
        self.grasps.iter().map(|(g, w)| (pose * g, *w)).collect()
    }

    /// Wireframe length a camera at the origin could see with the model at `pose` (lines with a
    /// face towards the camera; other objects may still hide them).
    pub fn visible_length(&self, pose: &Isometry3<f64>) -> f64 {
        let eye = eye_of(pose);
        (0..self.lines.len()).filter(|&k| self.faces_eye(k, &eye)).map(|k| self.lines[k].len).sum()
    }
}

/// Where the camera (the origin of `cam`) lies in the model's frame with the model at `pose`.
pub(crate) fn eye_of(pose: &Isometry3<f64>) -> Point3<f64> {
    Point3::from(-pose.rotation.inverse_transform_vector(&pose.translation.vector))
}

/// See [`MatcherModel::may_be_seen`]: a face turned away by up to about 6 degrees past edge-on
/// still counts as seen. The first look gives up hypotheses that put either seed line where
/// it may not be seen: 35% of those left after [`super::table::hopelessly_sunk`] on the bench
/// scene. On the tuning seeds (`marvin eval locate`, `widgets.toml` 1-500, `dense.toml` and
/// `side_light.toml` 1-200) 1 / 5 / 0 objects more, 1 / 1 / 0 false reports more (L-brackets
/// turned over on 0.15-0.16 of their wireframe: the places' floors now fall to others).
pub(crate) const SEEN_SLACK: f64 = 0.1;

pub use crate::front_end::workspace::Table;

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
    /// Instances of one model sought at most. Some a search finds are other parts read as
    /// this model (an L-bracket in a U-channel's corner, a block on a widget's lines) that the
    /// merge sets aside later, so this must leave room beyond the copies a scene holds. On
    /// tuning seeds (`marvin eval locate`, `dense.toml` 1-200, up to three copies of a model)
    /// 4 instead of 3 located 85.7% -> 87.2% with 25 -> 26 false reports, and left
    /// `widgets.toml` 1-500 and `side_light.toml` 1-200 word for word the same; 5 found 0.5
    /// points more for two false reports more, 6 no more than 5.
    ///
    /// Raised to 6 in session 71, the realistic cell's checks having grown since: a U-channel
    /// read where an L-bracket lay came from a bracket search that had spent its four on
    /// brackets in the channels' corners before it reached the bracket there (realistic
    /// `dense.toml` tuning seeds 5136, 5149, 5291, 5376). Through tuning seed 1's calibrations,
    /// realistic `dense.toml` 5001-5400: 4 located 0.9176 with 67 false reports, 5 0.9241 / 66,
    /// 6 0.9248 / 64, 8 0.9250 / 64; ideal `dense.toml` 5001-5200: 0.9443 / 22 -> 0.9496 / 19
    /// (6 and 8 alike); realistic `widgets.toml` 4401-4700 (one copy of each model) the same,
    /// 0.9799 / 8. Run once after the choice, fresh realistic `dense.toml` 5701-6000: 0.9167 /
    /// 38 -> 0.9225 / 39. The match's median time the same (29.8 / 29.1 ms).
    pub max_instances: usize,
    /// Hypotheses kept for verification per search: the best supported, no two alike.
    pub hypotheses: usize,
    /// With the image at hand, a located object's camera-facing wireframe must run along
    /// edgels for at least this fraction of its length.
    pub min_image_support: f64,
    /// The table the parts rest on, where the cell's layout is known: readings through its top
    /// are refused ([`super::table`]).
    #[serde(default)]
    pub table: Option<Table>,
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
            max_instances: 6,
            hypotheses: 12,
            min_image_support: 0.5,
            table: None,
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
pub(crate) fn separation(p: &Point3<f64>, u: &Vector3<f64>, q: &Point3<f64>, v: &Vector3<f64>) -> f64 {
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
pub(crate) fn closest_params(p: &Point3<f64>, u: &Vector3<f64>, q: &Point3<f64>, v: &Vector3<f64>) -> (f64, f64) {
    let w = p - q;
    let (b, d, e) = (u.dot(v), u.dot(&w), v.dot(&w));
    let den = 1.0 - b * b;
    if den < 1e-12 {
        return (0.0, 0.0);
    }
    ((b * e - d) / den, (e - b * d) / den)
}

/// A focus line and one of its feature group, with their relations: angle, separation, and
/// where along each their closest approach falls.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FocusPair {
    pub(crate) focus: usize,
    pub(crate) partner: usize,
    pub(crate) angle: f64,
    pub(crate) separation: f64,
    pub(crate) at_focus: f64,
    pub(crate) at_partner: f64,
}

/// Which model lines a scene line can lie along, by where its ends fall in the model's frame:
/// a grid of cubic cells over the model's bounding sphere (and a margin), each with a bit per
/// model line whose infinite line passes near enough the cell that a point in it may lie
/// within the support distance. A scene line can support only the lines of both its ends'
/// cells; counting support over those alone instead of every model line near the pose made
/// the support count (most of the matcher's time) several times cheaper, with the same result.
#[derive(Clone)]
pub(crate) struct LineGrid {
    pub(crate) support_distance: f64,
    origin: Point3<f64>,
    cell: f64,
    /// Cells per metre (a multiplication is cheaper than a division, and this is looked up
    /// twice per scene line per hypothesis).
    per_metre: f64,
    cells: [usize; 3],
    cells_f64: [f64; 3],
    /// Bits per cell, `words` words each.
    words: usize,
    bits: Vec<u64>,
    /// Every line's bit.
    all: Vec<u64>,
    /// The directions the model's lines run in, each once (to within [`SAME_DIRECTION`]).
    directions: Vec<Vector3<f64>>,
}

/// Line directions whose cosine differs from 1 by less than this are taken as one in
/// [`LineGrid::may_run_along`]; its test is widened by as much, so that it never rules out a
/// line that the exact test would let through.
const SAME_DIRECTION: f64 = 1e-9;

/// The directions of `model`'s lines, parallel and opposite ones once.
fn distinct_directions(model: &MatcherModel) -> Vec<Vector3<f64>> {
    let mut out: Vec<Vector3<f64>> = Vec::new();
    for l in &model.lines {
        if !out.iter().any(|d| d.dot(&l.dir).abs() > 1.0 - SAME_DIRECTION) {
            out.push(l.dir);
        }
    }
    out
}

/// Cells are this many support distances wide.
const GRID_CELL: f64 = 2.0;
/// The grid reaches this far (metres) beyond the model's bounding sphere: scene lines whose
/// midpoints fall within the sphere reach out of it by half their length.
const GRID_MARGIN: f64 = 0.02;

impl std::fmt::Debug for LineGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "LineGrid({:?} cells of {} m)", self.cells, self.cell)
    }
}

impl LineGrid {
    pub(crate) fn new(model: &MatcherModel, support_distance: f64) -> LineGrid {
        let (centre, radius) = model.sphere;
        let half = radius + support_distance + GRID_MARGIN;
        let cell = (GRID_CELL * support_distance).max(1e-4);
        let n = ((2.0 * half / cell).ceil() as usize).max(1);
        let origin = centre - Vector3::repeat(half);
        let words = model.lines.len().div_ceil(64).max(1);
        let mut bits = vec![0u64; n * n * n * words];
        // A point of the cell lies within the support distance of a line only if its centre
        // lies within that plus half the cell's diagonal.
        let reach = support_distance + 0.5 * cell * 3f64.sqrt();
        for (c, cell_bits) in bits.chunks_mut(words).enumerate() {
            let index = [c % n, (c / n) % n, c / (n * n)];
            let at = origin + Vector3::from_fn(|k, _| (index[k] as f64 + 0.5) * cell);
            for (i, l) in model.lines.iter().enumerate() {
                let w = at - l.a;
                if (w - l.dir * w.dot(&l.dir)).norm_squared() <= reach * reach {
                    cell_bits[i / 64] |= 1 << (i % 64);
                }
            }
        }
        let mut all = vec![0u64; words];
        for i in 0..model.lines.len() {
            all[i / 64] |= 1 << (i % 64);
        }
        LineGrid {
            support_distance,
            origin,
            cell,
            per_metre: 1.0 / cell,
            cells: [n; 3],
            cells_f64: [n as f64; 3],
            words,
            bits,
            all,
            directions: distinct_directions(model),
        }
    }

    /// Whether a scene line running along `dir` (model frame) is within the angle whose cosine
    /// is `cos_tolerance` of some model line's direction: one that is not lies along none of
    /// them ([`super::support::overlap`] gives every line nought). Most lines near a wrong pose
    /// run in none of the model's few directions, and this test costs a tenth of looking up
    /// both ends' cells.
    pub(crate) fn may_run_along(&self, dir: &Vector3<f64>, cos_tolerance: f64) -> bool {
        self.directions.iter().any(|d| d.dot(dir).abs() >= cos_tolerance - 2.0 * SAME_DIRECTION)
    }

    /// The bits of the cell holding `x` (model frame), if the grid reaches it.
    fn cell_bits(&self, x: &Point3<f64>) -> Option<&[u64]> {
        let mut at = 0;
        for k in (0..3).rev() {
            let f = (x[k] - self.origin[k]) * self.per_metre;
            if !(0.0..self.cells_f64[k]).contains(&f) {
                return None;
            }
            // Truncation is the floor here, off the grid's negative side being ruled out
            // first; and through `u32`, which the processor converts to in one instruction
            // (to `usize` it takes a dozen, and this runs six times per scene line per
            // hypothesis).
            at = at * self.cells[k] + f as u32 as usize;
        }
        Some(&self.bits[at * self.words..(at + 1) * self.words])
    }

    /// The model lines a scene line with `ends` (model frame) may lie along: those of both
    /// ends' cells (of either, where the other is off the grid; all, where both are or where
    /// the ends are not given).
    #[cfg(test)]
    pub(crate) fn lines_along(&self, ends: Option<&(Point3<f64>, Point3<f64>)>) -> impl Iterator<Item = usize> + '_ {
        let mut lines = Vec::new();
        self.each_line_along(ends, |i| lines.push(i));
        lines.into_iter()
    }

    /// Hands `each` the lines of [`LineGrid::lines_along`], in order, without an iterator
    /// (the support count's inner loop: the flattened iterator over the words was a fiftieth of
    /// the matcher's instructions).
    pub(crate) fn each_line_along(&self, ends: Option<&(Point3<f64>, Point3<f64>)>, mut each: impl FnMut(usize)) {
        let (ba, bb) = ends.map_or((None, None), |(a, b)| (self.cell_bits(a), self.cell_bits(b)));
        for w in 0..self.words {
            let mut word = match (ba, bb) {
                (Some(x), Some(y)) => x[w] & y[w],
                (Some(x), None) | (None, Some(x)) => x[w],
                (None, None) => self.all[w],
            };
            while word != 0 {
                each(w * 64 + word.trailing_zeros() as usize);
                word &= word - 1;
            }
        }
    }
}
