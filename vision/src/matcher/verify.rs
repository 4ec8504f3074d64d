//! Verification against accidental matches in the image: a located model's wireframe, projected
//! into the left image where its pose turns its faces to the camera, must run along edgels that
//! Canny found there (whether or not stereo recovered them). A pose that only happens to line up
//! a few 3D lines of other objects finds little such evidence. The later looks also ask how
//! much of a candidate's wireframe the objects already located explain ([`Explained`]).

use super::depths::EdgelDepths;
use super::model::MatcherModel;
use crate::front_end::canny::{EdgeMap, Edgel};
use crate::image::{floor_int, nearest_px};
use mesh::PinholeCamera;
use nalgebra::{Isometry3, Point2, Vector2};

/// What the image offers to verify against: the left camera, its edgels, the straight image
/// lines stereo did not lift to 3D (mostly edges near the rasters' direction), from a
/// front-end run the depths stereo gave the edgels it matched, and from a calibrated pair the
/// right image's edgels ([`RightImage`]).
pub struct ImageEvidence<'a> {
    pub cam: &'a PinholeCamera,
    pub edges: &'a EdgeMap,
    pub lines: Vec<ImageLine>,
    /// The image lines stereo did lift to 3D (from a front-end run; none otherwise): where the
    /// lift went wrong, a part's outline is still seen in them ([`super::image_look`]).
    pub(crate) lifted: std::sync::Arc<Vec<ImageLine>>,
    /// The edgels spread into an orientation mask, so that each sample is one look-up.
    mask: std::sync::Arc<EdgeMask>,
    /// The depths stereo gave the left image's matched edgels, by pixel (none without stereo).
    pub(crate) depths: Option<std::sync::Arc<EdgelDepths>>,
    /// The pair's other image (none for the left image alone).
    pub right: Option<std::sync::Arc<RightImage<'a>>>,
}

/// The right image of the pair, for fitting poses to both images at once
/// ([`super::polish`]): its camera's edgels, and where that camera sits from the left one.
pub struct RightImage<'a> {
    pub ev: ImageEvidence<'a>,
    pub right_from_cam: Isometry3<f64>,
}

/// A straight line of the left image, in pixels, with the plane through the camera centre that
/// holds it (unit normal, `cam` frame): a 3D edge seen as this line lies in that plane.
#[derive(Debug, Clone, Copy)]
pub struct ImageLine {
    pub a: nalgebra::Point2<f64>,
    pub b: nalgebra::Point2<f64>,
    pub normal: nalgebra::Vector3<f64>,
}

/// Image lines shorter than this (pixels) are not used.
const MIN_IMAGE_LINE_PX: f64 = 20.0;

impl<'a> ImageEvidence<'a> {
    pub fn new(cam: &'a PinholeCamera, edges: &'a EdgeMap, lines: Vec<ImageLine>) -> ImageEvidence<'a> {
        let mask = std::sync::Arc::new(EdgeMask::of(edges));
        ImageEvidence { cam, edges, lines, lifted: Default::default(), mask, depths: None, right: None }
    }

    /// The first edgel within [`NEAR_PX`] across a line running along `dir` through (`x`, `y`)
    /// whose edge runs within [`ALONG_RAD`] of it.
    pub(crate) fn edgel_near(&self, x: f64, y: f64, dir: Vector2<f64>) -> Option<&'a Edgel> {
        edgel_near(self.edges, &self.mask, x, y, dir)
    }

    /// The direction along the edge of edgel `i` (unit, perpendicular to its gradient).
    pub(crate) fn tangent(&self, i: u32) -> Vector2<f64> {
        self.mask.tangents[i as usize]
    }

    /// Whether an edgel was found at row-major pixel `pixel` (cheaper to ask than the edge map).
    pub(crate) fn occupied(&self, pixel: usize) -> bool {
        self.mask.occupied(pixel)
    }

    /// The orientation bins of the edges that run within [`ALONG_RAD`] of image direction
    /// `dir` (and perhaps one bin more), for [`ImageEvidence::may_hold_across`].
    pub(crate) fn bins_along(dir: Vector2<f64>) -> u32 {
        EdgeMask::bins_along(dir)
    }

    /// Whether an edgel of one of `bins` may lie at a pixel nearest some point `u + offset *
    /// normal` of a stretch along the normal, the stretch given by [`looks_across`]: `false`
    /// only when none does.
    pub(crate) fn may_hold_across(&self, u: &Point2<f64>, normal: &Vector2<f64>, looks: &[f64], bins: u32) -> bool {
        looks.iter().any(|&offset| {
            let q = u + normal * offset;
            self.mask.any_near(q.x, q.y, bins)
        })
    }

    /// The same edgels with other image lines.
    pub(crate) fn with_lines(&self, lines: Vec<ImageLine>) -> ImageEvidence<'a> {
        ImageEvidence {
            cam: self.cam,
            edges: self.edges,
            lines,
            lifted: self.lifted.clone(),
            mask: self.mask.clone(),
            depths: self.depths.clone(),
            right: self.right.clone(),
        }
    }

    /// The evidence of one front-end run on the left camera `cam`.
    pub fn of(cam: &'a PinholeCamera, fe: &'a crate::front_end::FrontEnd) -> ImageEvidence<'a> {
        let lifted: std::collections::HashSet<u32> = fe.lines3d.iter().map(|l| l.line2).collect();
        let (mut lines, mut lifted_lines) = (Vec::new(), Vec::new());
        if let Some(rect) = &fe.rect {
            for (i, l) in fe.lines2d.iter().enumerate().filter(|(_, l)| l.length() as f64 >= MIN_IMAGE_LINE_PX) {
                let px = |p: [f32; 2]| {
                    let (x, y) = rect.from_rectified(crate::front_end::rectify::Side::Left, p[0] as f64, p[1] as f64);
                    nalgebra::Point2::new(x, y)
                };
                let (a, b) = (px(l.start), px(l.end));
                let normal = cam.ray_cam(a.x, a.y).cross(&cam.ray_cam(b.x, b.y)).normalize();
                let to = if lifted.contains(&(i as u32)) { &mut lifted_lines } else { &mut lines };
                to.push(ImageLine { a, b, normal });
            }
        }
        let mut ev = ImageEvidence::new(cam, &fe.left, lines);
        ev.lifted = std::sync::Arc::new(lifted_lines);
        ev.depths = fe.rect.as_ref().map(|rect| std::sync::Arc::new(EdgelDepths::of(fe, rect)));
        ev
    }

    /// The evidence of one front-end run on a calibrated pair: [`ImageEvidence::of`] the left
    /// image, with the right image's edgels.
    pub fn of_pair(calib: &'a mesh::StereoCalibration, fe: &'a crate::front_end::FrontEnd) -> ImageEvidence<'a> {
        // Each image's edgels laid out at once, on two threads.
        let (left, right) = rayon::join(
            || ImageEvidence::of(&calib.left, fe),
            || ImageEvidence::new(&calib.right, &fe.right, Vec::new()),
        );
        let right_from_cam = calib.right.cam_from_world() * calib.left.world_from_cam;
        left.with_right(RightImage { ev: right, right_from_cam })
    }

    /// The same evidence with the pair's right image.
    pub fn with_right(mut self, right: RightImage<'a>) -> ImageEvidence<'a> {
        self.right = Some(std::sync::Arc::new(right));
        self
    }

    /// The same evidence with stereo's depths at the edgels.
    #[cfg(test)]
    pub(crate) fn with_depths(mut self, depths: EdgelDepths) -> ImageEvidence<'a> {
        self.depths = Some(std::sync::Arc::new(depths));
        self
    }
}

/// Along the camera-facing wireframe of `model` at `pose` that none of `solids` hides: the
/// length (pixels) where an edgel's stereo depth agrees with the model's, and where edgels
/// have depths and none agrees (`None` without stereo depths).
pub fn depth_agreement(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    ev: &ImageEvidence,
    solids: &[&super::occlusion::Solid],
) -> Option<(f64, f64)> {
    let depths = ev.depths.as_ref()?;
    let (mut agree, mut disagree) = (0.0, 0.0);
    for (_, [a3, b3], [a, b]) in facing_lines(model, pose, ev.cam) {
        let len = (b - a).norm();
        if len < 2.0 * STEP_PX {
            continue;
        }
        let steps = (len / STEP_PX) as usize;
        for k in 1..steps {
            let f = k as f64 / steps as f64;
            let p3 = a3 + (b3 - a3) * f;
            if solids.iter().any(|s| s.hides(&p3)) {
                continue;
            }
            let q = a + (b - a) * f;
            match depths.agree(ev.edges, q.x, q.y, p3.z, DEPTH_TOLERANCE_PX) {
                Some(true) => agree += STEP_PX,
                Some(false) => disagree += STEP_PX,
                None => {}
            }
        }
    }
    Some((agree, disagree))
}

/// A matched edgel's depth agrees with a model's within this much disparity (pixels): three
/// times the spread of PMF's matches about the truth (96% within 0.5 px).
pub const DEPTH_TOLERANCE_PX: f64 = 1.5;

/// Image samples taken every this many pixels along a projected line.
const STEP_PX: f64 = 2.0;
/// An edgel within this distance (pixels)...
const NEAR_PX: f64 = 1.5;
/// ...whose edge runs within this angle (radians) of the projected line counts as evidence.
pub(crate) const ALONG_RAD: f64 = 0.35;

/// Each line of `model` that `pose` turns towards the camera, its index, with its ends in `cam` and their
/// image points (lines with an end behind the camera are left out).
fn facing_lines<'m>(
    model: &'m MatcherModel,
    pose: &'m Isometry3<f64>,
    cam: &'m PinholeCamera,
) -> impl Iterator<Item = (usize, [nalgebra::Point3<f64>; 2], [Point2<f64>; 2])> + 'm {
    let eye = super::model::eye_of(pose);
    model.lines.iter().enumerate().filter(move |(k, _)| model.faces_eye(*k, &eye)).filter_map(move |(k, line)| {
        let (a3, b3) = (pose * line.a, pose * line.b);
        Some((k, [a3, b3], [cam.project_cam(&a3)?, cam.project_cam(&b3)?]))
    })
}

/// The fraction of the projected, camera-facing wireframe (by length in the image) that runs
/// along edgels.
pub fn image_support(model: &MatcherModel, pose: &Isometry3<f64>, ev: &ImageEvidence) -> f64 {
    image_support_at_least(model, pose, ev, 0.0).unwrap_or(0.0)
}

/// The length (pixels) of the projected, camera-facing wireframe that [`image_support`] samples:
/// what the image should show of the model at `pose`.
pub fn facing_length_px(model: &MatcherModel, pose: &Isometry3<f64>, cam: &PinholeCamera) -> f64 {
    facing_lines(model, pose, cam)
        .map(|(_, _, [a, b])| (b - a).norm())
        .filter(|len| *len >= 2.0 * STEP_PX)
        .map(|len| STEP_PX * ((len / STEP_PX) as usize - 1) as f64)
        .sum()
}

/// [`image_support`], given up (`None`) as soon as it cannot reach `min`: the samples are laid
/// out first, and the count stops when even all the samples left could not lift it to `min`.
pub fn image_support_at_least(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    ev: &ImageEvidence,
    min: f64,
) -> Option<f64> {
    image_support_shown_at_least(model, pose, ev, min, &[])
}

/// [`image_support_at_least`] without the lines `dim` marks (as [`image_support_shown`]).
pub fn image_support_shown_at_least(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    ev: &ImageEvidence,
    min: f64,
    dim: &[bool],
) -> Option<f64> {
    let mut segments = Vec::with_capacity(model.lines.len());
    let mut all = 0.0;
    for (k, _, [a, b]) in facing_lines(model, pose, ev.cam) {
        let len = (b - a).norm();
        if len < 2.0 * STEP_PX || dim.get(k).copied().unwrap_or(false) {
            continue;
        }
        let steps = (len / STEP_PX) as usize;
        all += STEP_PX * (steps - 1) as f64;
        let dir = (b - a) / len;
        segments.push((a, b, dir, EdgeMask::bins_along(dir), steps));
    }
    if all <= 0.0 {
        return (min <= 0.0).then_some(0.0);
    }
    let (mut seen, mut missed) = (0.0, 0.0);
    for (a, b, dir, bins, steps) in segments {
        for k in 1..steps {
            let q = a + (b - a) * (k as f64 / steps as f64);
            if ev.mask.any_near(q.x, q.y, bins) && edgel_along(ev.edges, &ev.mask, q.x, q.y, dir) {
                seen += STEP_PX;
            } else {
                missed += STEP_PX;
                if (all - missed) / all < min {
                    return None;
                }
            }
        }
    }
    Some(seen / all)
}

/// [`image_support`] counted only over the part of the camera-facing wireframe that none of
/// `solids` hides (hidden samples count neither way), with that part's share of the whole
/// (both 0 when nothing faces the camera).
pub fn image_support_unhidden(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    ev: &ImageEvidence,
    solids: &[&super::occlusion::Solid],
) -> (f64, f64) {
    let (seen, unhidden, _) = image_support_shown(model, pose, ev, solids, &[]);
    (seen, unhidden)
}

/// [`image_support_unhidden`] without the lines `dim` marks (edges the light leaves too faint
/// to show, [`super::contrast::Shown::dim_lines`]; none past its end): the share of the rest
/// that runs along edgels, the unhidden share of the whole, and the share of the unhidden
/// that is not dim.
pub fn image_support_shown(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    ev: &ImageEvidence,
    solids: &[&super::occlusion::Solid],
    dim: &[bool],
) -> (f64, f64, f64) {
    let (mut seen, mut shown, mut unhidden, mut all) = (0.0, 0.0, 0.0, 0.0);
    for (k, [a3, b3], [a, b]) in facing_lines(model, pose, ev.cam) {
        let len = (b - a).norm();
        if len < 2.0 * STEP_PX {
            continue;
        }
        let steps = (len / STEP_PX) as usize;
        let (dir, bins) = ((b - a) / len, EdgeMask::bins_along((b - a) / len));
        let is_dim = dim.get(k).copied().unwrap_or(false);
        for s in 1..steps {
            let f = s as f64 / steps as f64;
            all += STEP_PX;
            if solids.iter().any(|s| s.hides(&(a3 + (b3 - a3) * f))) {
                continue;
            }
            unhidden += STEP_PX;
            if is_dim {
                continue;
            }
            shown += STEP_PX;
            let q = a + (b - a) * f;
            if ev.mask.any_near(q.x, q.y, bins) && edgel_along(ev.edges, &ev.mask, q.x, q.y, dir) {
                seen += STEP_PX;
            }
        }
    }
    if shown <= 0.0 { (0.0, unhidden / all.max(1e-12), 0.0) } else { (seen / shown, unhidden / all, shown / unhidden) }
}

/// The camera-facing wireframe of `model` at `pose` where it runs further than `apart_px` in
/// the image from every camera-facing line of `other` at `other_pose`, neither `model`'s own
/// body nor any of `solids` hiding it, and off the edges `explained` holds (other objects'
/// edgels say nothing of this one): the share of that part that runs along edgels, and its
/// length (pixels); the length that `solids` or the image's border kept from view; and the
/// length whose points lie where `taken` says something else is ([`Beyond`]). What the image shows of a larger model beyond a smaller one it holds
/// ([`super::superset`]).
pub fn image_support_beyond(
    (model, pose): (&MatcherModel, &Isometry3<f64>),
    (other, other_pose): (&MatcherModel, &Isometry3<f64>),
    ev: &ImageEvidence,
    solids: &[&super::occlusion::Solid],
    explained: &Explained,
    apart_px: f64,
    taken: &dyn Fn(&nalgebra::Point3<f64>) -> bool,
) -> Beyond {
    let theirs: Vec<[Point2<f64>; 2]> = facing_lines(other, other_pose, ev.cam).map(|(_, _, ends)| ends).collect();
    let near_theirs = |q: &Point2<f64>| {
        theirs.iter().any(|[a, b]| {
            let ab = b - a;
            let t = ((q - a).dot(&ab) / ab.norm_squared().max(1e-12)).clamp(0.0, 1.0);
            (a + ab * t - q).norm() <= apart_px
        })
    };
    let (mut seen, mut beyond, mut kept_from_view, mut taken_px) = (0.0, 0.0, 0.0, 0.0);
    let own = super::occlusion::Solid::new(model, pose);
    let in_frame =
        |q: &Point2<f64>| (0.0..ev.edges.width as f64).contains(&q.x) && (0.0..ev.edges.height as f64).contains(&q.y);
    for (_, [a3, b3], [a, b]) in facing_lines(model, pose, ev.cam) {
        let len = (b - a).norm();
        if len < 2.0 * STEP_PX {
            continue;
        }
        let steps = (len / STEP_PX) as usize;
        let (dir, bins) = ((b - a) / len, EdgeMask::bins_along((b - a) / len));
        for s in 1..steps {
            let f = s as f64 / steps as f64;
            let q = a + (b - a) * f;
            let x3 = a3 + (b3 - a3) * f;
            if near_theirs(&q) {
                continue;
            }
            if taken(&x3) {
                taken_px += STEP_PX;
            }
            if own.hides(&x3) {
                continue;
            }
            if !in_frame(&q) || solids.iter().any(|s| s.hides(&x3)) {
                kept_from_view += STEP_PX;
                continue;
            }
            if explained.explains(&q, &dir) {
                continue;
            }
            beyond += STEP_PX;
            if ev.mask.any_near(q.x, q.y, bins) && edgel_along(ev.edges, &ev.mask, q.x, q.y, dir) {
                seen += STEP_PX;
            }
        }
    }
    Beyond {
        share: if beyond > 0.0 { seen / beyond } else { 0.0 },
        px: beyond,
        kept_from_view_px: kept_from_view,
        taken_px,
    }
}

/// What [`image_support_beyond`] found of a larger model beyond a smaller one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Beyond {
    /// The share of the length looked at that runs along edgels.
    pub share: f64,
    /// The length looked at (pixels).
    pub px: f64,
    /// The length that other objects' bodies hide or that falls outside the image (pixels):
    /// what the image could not show even if the larger model lay there.
    pub kept_from_view_px: f64,
    /// The length (pixels, hidden or not) whose points `taken` says something else fills: where
    /// the larger model could not lie.
    pub taken_px: f64,
}

/// The image edges of the objects located so far (their camera-facing wireframes, projected):
/// evidence those objects already account for. A later candidate whose wireframe runs mostly
/// along them shows nothing of its own (an L-bracket read into a U-channel's corner does).
pub struct Explained {
    /// Image segments, with their unit directions.
    segments: Vec<(Point2<f64>, Point2<f64>, Vector2<f64>)>,
}

/// Whether image point `q` on a line running along `dir` lies on one of `segments` (ends and unit
/// direction) that runs along it.
fn explained_by<'s>(
    mut segments: impl Iterator<Item = &'s (Point2<f64>, Point2<f64>, Vector2<f64>)>,
    q: &Point2<f64>,
    dir: &Vector2<f64>,
) -> bool {
    let cos_along = ALONG_RAD.cos();
    segments.any(|(a, b, d)| {
        if d.dot(dir).abs() < cos_along {
            return false;
        }
        let t = (q - a).dot(d).clamp(0.0, (b - a).norm());
        (q - (a + d * t)).norm() <= EXPLAINED_PX
    })
}

/// A candidate of a later look whose wireframe runs along located objects' edges for more than
/// this share of its length is not admitted.
pub const MAX_EXPLAINED: f64 = 0.5;

/// A sample lies on a located object's edge within this distance (pixels).
const EXPLAINED_PX: f64 = 2.0;

impl Explained {
    /// The edges of `located` (models at their poses, `cam` frame) as camera `cam` sees them.
    pub fn of<'m>(
        located: impl IntoIterator<Item = (&'m MatcherModel, &'m Isometry3<f64>)>,
        cam: &PinholeCamera,
    ) -> Explained {
        let mut segments = Vec::new();
        for (model, pose) in located {
            for (_, _, [a, b]) in facing_lines(model, pose, cam).filter(|(_, _, [a, b])| (b - a).norm() > 1e-9) {
                segments.push((a, b, (b - a).normalize()));
            }
        }
        Explained { segments }
    }

    /// Whether image point `q` on a line running along `dir` lies on one of the edges.
    fn explains(&self, q: &Point2<f64>, dir: &Vector2<f64>) -> bool {
        explained_by(self.segments.iter(), q, dir)
    }

    /// The share of image line `l` (by length) that runs along the edges.
    pub fn share_of_line(&self, l: &ImageLine) -> f64 {
        let len = (l.b - l.a).norm();
        if len < 2.0 * STEP_PX {
            return 0.0;
        }
        let (steps, dir) = ((len / STEP_PX) as usize, (l.b - l.a) / len);
        // Only edges that run along the line and come within reach of its box can explain a
        // sample of it: picked once, not at every sample.
        let (lo, hi) = (
            l.a.coords.inf(&l.b.coords).add_scalar(-EXPLAINED_PX),
            l.a.coords.sup(&l.b.coords).add_scalar(EXPLAINED_PX),
        );
        let near: Vec<&(Point2<f64>, Point2<f64>, Vector2<f64>)> = self
            .segments
            .iter()
            .filter(|(a, b, _)| {
                let (slo, shi) = (a.coords.inf(&b.coords), a.coords.sup(&b.coords));
                slo.x <= hi.x && slo.y <= hi.y && shi.x >= lo.x && shi.y >= lo.y
            })
            .collect();
        let explained = (1..steps)
            .filter(|&k| explained_by(near.iter().copied(), &(l.a + (l.b - l.a) * (k as f64 / steps as f64)), &dir))
            .count();
        explained as f64 / (steps - 1) as f64
    }

    /// The share of `model`'s camera-facing wireframe at `pose` (by image length) that runs
    /// along the edges.
    pub fn share(&self, model: &MatcherModel, pose: &Isometry3<f64>, cam: &PinholeCamera) -> f64 {
        let (mut explained, mut all) = (0.0, 0.0);
        for (_, _, [a, b]) in facing_lines(model, pose, cam) {
            let len = (b - a).norm();
            if len < 2.0 * STEP_PX {
                continue;
            }
            let (steps, dir) = ((len / STEP_PX) as usize, (b - a) / len);
            for k in 1..steps {
                all += STEP_PX;
                if self.explains(&(a + (b - a) * (k as f64 / steps as f64)), &dir) {
                    explained += STEP_PX;
                }
            }
        }
        if all <= 0.0 { 0.0 } else { explained / all }
    }
}

/// Per pixel, a bit for each orientation (of 32 across 180 deg) of the edgels that the exact
/// test ([`edgel_along`]) would look at from there. Laid out once per image, it settles most
/// samples with one look-up, since a sample off the model's true place mostly finds no edgel
/// at all: searching every sample's neighbourhood took most of the verification time.
struct EdgeMask {
    width: usize,
    height: usize,
    bits: Vec<u32>,
    /// A bit per pixel (row-major, 64 to a word): whether an edgel was found there. The searches
    /// across model edges look at many pixels, most of them empty: this answers them from 32
    /// KB, where the edge map's per-pixel index takes a megabyte.
    occupied: Vec<u64>,
    /// Each edgel's direction along its edge (unit, perpendicular to its gradient), worked
    /// out once per image: the image checks look at each edgel many times, and the sine and
    /// cosine cost more than the rest of a look.
    tangents: Vec<Vector2<f64>>,
}

/// Orientation bins of the mask.
const BINS: f64 = 32.0;

/// `y.atan2(x)` to within [`ROUGH_ATAN2_RAD`], without the library's call: the arctangent of
/// the smaller over the larger magnitude by `pi/4 z - z (z - 1) (0.2447 + 0.0663 z)` on [0, 1]
/// (within 0.0015 rad), turned into the right octant.
fn rough_atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = (ax.min(ay), ax.max(ay));
    if large == 0.0 {
        return 0.0;
    }
    let z = small / large;
    let mut a = std::f64::consts::FRAC_PI_4 * z - z * (z - 1.0) * (0.2447 + 0.0663 * z);
    if ay > ax {
        a = std::f64::consts::FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = std::f64::consts::PI - a;
    }
    if y < 0.0 { -a } else { a }
}

/// How far [`rough_atan2`] may be off (radians), with room to spare.
const ROUGH_ATAN2_RAD: f64 = 0.005;

impl EdgeMask {
    fn of(edges: &EdgeMap) -> EdgeMask {
        let (width, height) = (edges.width, edges.height);
        let mut bits = vec![0u32; width * height];
        let r = SCAN_PX;
        for (e, &pixel) in edges.edgels.iter().zip(&edges.pixel) {
            let bit = 1u32 << Self::bin(e.orientation as f64);
            let (cx, cy) = (pixel as usize % width, pixel as usize / width);
            for py in cy.saturating_sub(r)..=(cy + r).min(height - 1) {
                for px in cx.saturating_sub(r)..=(cx + r).min(width - 1) {
                    bits[py * width + px] |= bit;
                }
            }
        }
        let mut occupied = vec![0u64; (width * height).div_ceil(64)];
        for &pixel in &edges.pixel {
            occupied[pixel as usize / 64] |= 1 << (pixel % 64);
        }
        let tangents = edges.edgels.iter().map(|e| tangent(e.orientation)).collect();
        EdgeMask { width, height, bits, occupied, tangents }
    }

    /// The bin of an edge whose gradient points along `angle` (edges are taken both ways round).
    fn bin(angle: f64) -> u32 {
        let a = angle.rem_euclid(std::f64::consts::PI);
        ((a / std::f64::consts::PI * BINS) as u32).min(BINS as u32 - 1)
    }

    /// Every bin holding orientations of edges that run within [`ALONG_RAD`] of image
    /// direction `dir` (and perhaps a bin more: the mask only rules samples out, and the
    /// direction's angle is taken from [`rough_atan2`], with [`ROUGH_ATAN2_RAD`] added each way;
    /// the library's `atan2` was a sixth of the image check's time).
    fn bins_along(dir: Vector2<f64>) -> u32 {
        let width = std::f64::consts::PI / BINS;
        let gradient = rough_atan2(dir.x, -dir.y).rem_euclid(std::f64::consts::PI) / width;
        let reach = (ALONG_RAD + ROUGH_ATAN2_RAD) / width;
        let (lo, hi) = (floor_int(gradient - reach), floor_int(gradient + reach));
        (lo..=hi).fold(0, |m, b| m | 1 << b.rem_euclid(BINS as i64))
    }

    /// Whether an edgel was found at row-major pixel `pixel`.
    fn occupied(&self, pixel: usize) -> bool {
        self.occupied[pixel / 64] & (1 << (pixel % 64)) != 0
    }

    /// Whether an edgel of one of `bins` lies in the neighbourhood [`edgel_along`] searches
    /// from image point (`x`, `y`).
    #[inline]
    fn any_near(&self, x: f64, y: f64, bins: u32) -> bool {
        // Just off the image the search still reaches its edge, whose pixels' bits cover it.
        let px = nearest_px(x).clamp(0, self.width as i64 - 1) as usize;
        let py = nearest_px(y).clamp(0, self.height as i64 - 1) as usize;
        self.bits[py * self.width + px] & bins != 0
    }
}

/// Whether an edgel lies within [`NEAR_PX`] across a line running along `dir` through (`x`,
/// `y`) with its edge within [`ALONG_RAD`] of it: [`edgel_near`]'s question, the same pixels
/// looked at, but nearest first and without a bounds test per pixel away from the image's
/// border. Most samples that get this far find their edgel in the first few pixels; scanned
/// row by row from a corner they took 7% of the matcher's instructions (callgrind), with many
/// mispredicted branches.
fn edgel_along(edges: &EdgeMap, mask: &EdgeMask, x: f64, y: f64, dir: Vector2<f64>) -> bool {
    let (cx, cy) = (nearest_px(x), nearest_px(y));
    let (w, h, r) = (edges.width as i64, edges.height as i64, SCAN_PX as i64);
    if cx < r || cy < r || cx + r >= w || cy + r >= h {
        return edgel_near(edges, mask, x, y, dir).is_some();
    }
    let centre = (cy * w + cx) as usize;
    let cos_along = ALONG_RAD.cos();
    NEAREST_FIRST.iter().any(|&(dx, dy)| {
        let pixel = centre.wrapping_add_signed(dy as isize * w as isize + dx as isize);
        if !mask.occupied(pixel) {
            return false;
        }
        let i = edges.at_pixel[pixel];
        if i == crate::front_end::canny::NO_EDGEL {
            return false;
        }
        let e = &edges.edgels[i as usize];
        let (ex, ey) = (e.x as f64 - x, e.y as f64 - y);
        (ex * dir.y - ey * dir.x).abs() <= NEAR_PX && mask.tangents[i as usize].dot(&dir).abs() >= cos_along
    })
}

/// How far (pixels, in x and in y) from a sample's pixel the edgel searches look.
const SCAN_PX: usize = NEAR_PX.ceil() as usize;

/// Where [`ImageEvidence::may_hold_across`] looks along the normal (pixels) for a stretch
/// `reach` either side of a sample, from the middle out, where a sample's own edgel mostly lies.
///
/// The mask holds each edgel's bin at every pixel within [`SCAN_PX`] (2) of its own in x and
/// y, and the nearest pixels of two points less than 2 px apart lie within 2 of each other; so
/// looks spaced under 4 px along the normal, each standing for the stretch within half that
/// either side, answer for the whole of it. (Just off the image, [`EdgeMask::any_near`] looks
/// at the edge's pixels, which lie nearer every pixel in the image.)
pub(crate) fn looks_across(reach: f64) -> Vec<f64> {
    let count = ((2.0 * reach / LOOK_SPACING_PX).ceil() as usize).max(1);
    let spacing = 2.0 * reach / count as f64;
    let middle = (count - 1) / 2;
    let outwards = |j: usize| if j % 2 == 1 { middle + j.div_ceil(2) } else { middle - j / 2 };
    (0..count).map(outwards).map(|i| spacing * (i as f64 + 0.5) - reach).collect()
}

/// The greatest spacing (pixels) of [`looks_across`]: each look answers for the points
/// within half of it, which must stay under [`SCAN_PX`].
const LOOK_SPACING_PX: f64 = 3.8;

/// The offsets of the pixels within [`SCAN_PX`] of a sample's, nearest first.
const NEAREST_FIRST: [(i8, i8); (2 * SCAN_PX + 1) * (2 * SCAN_PX + 1)] = [
    (0, 0),
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
    (2, 0),
    (-2, 0),
    (0, 2),
    (0, -2),
    (2, 1),
    (2, -1),
    (-2, 1),
    (-2, -1),
    (1, 2),
    (-1, 2),
    (1, -2),
    (-1, -2),
    (2, 2),
    (2, -2),
    (-2, 2),
    (-2, -2),
];

/// The direction along the edge of an edgel whose gradient points along `orientation`.
fn tangent(orientation: f32) -> Vector2<f64> {
    let (s, c) = (orientation as f64).sin_cos();
    Vector2::new(-s, c)
}

/// The first edgel of `edges` (laid out in `mask`) found within [`NEAR_PX`] across a line
/// running along `dir` through (`x`, `y`) whose edge runs within [`ALONG_RAD`] of it.
fn edgel_near<'e>(edges: &'e EdgeMap, mask: &EdgeMask, x: f64, y: f64, dir: Vector2<f64>) -> Option<&'e Edgel> {
    let (cx, cy) = (nearest_px(x), nearest_px(y));
    let r = SCAN_PX as i64;
    for py in cy - r..=cy + r {
        for px in cx - r..=cx + r {
            if px < 0 || py < 0 || px >= edges.width as i64 || py >= edges.height as i64 {
                continue;
            }
            let Some(i) = edges.edgel_at(px as usize, py as usize) else { continue };
            let e = &edges.edgels[i as usize];
            let (dx, dy) = (e.x as f64 - x, e.y as f64 - y);
            // Distance across the line, and the edge's own direction.
            if (dx * dir.y - dy * dir.x).abs() <= NEAR_PX
                && mask.tangents[i as usize].dot(&dir).abs() >= ALONG_RAD.cos()
            {
                return Some(e);
            }
        }
    }
    None
}

/// Test scenes: what Canny and the line finder would give for a model alone in view.
#[cfg(test)]
pub(crate) mod drawn {
    use super::*;
    use crate::front_end::canny::Edgel;

    /// Edgels one pixel apart along every camera-facing edge of `model` at `pose` (a 512 x 512
    /// image), and an image line along each such edge.
    pub fn model_edges(model: &MatcherModel, pose: &Isometry3<f64>, cam: &PinholeCamera) -> (EdgeMap, Vec<ImageLine>) {
        let mut edges = EdgeMap::new(512, 512);
        let mut lines = Vec::new();
        for (a, b) in model
            .lines
            .iter()
            .enumerate()
            .filter(|(k, _)| model.faces_camera(*k, pose))
            .filter_map(|(_, line)| Some((cam.project_cam(&(pose * line.a))?, cam.project_cam(&(pose * line.b))?)))
        {
            let d = (b - a).normalize();
            let steps = (b - a).norm() as usize;
            for s in 0..=steps {
                let q = a + (b - a) * (s as f64 / steps.max(1) as f64);
                let (x, y) = (q.x.round() as usize, q.y.round() as usize);
                if x < 512 && y < 512 && edges.edgel_at(x, y).is_none() {
                    let orientation = d.x.atan2(-d.y) as f32; // the gradient, across the edge
                    edges.push(
                        y * 512 + x,
                        Edgel { x: q.x as f32, y: q.y as f32, orientation, contrast: 50.0, sides: [0.0; 2] },
                    );
                }
            }
            let normal = cam.ray_cam(a.x, a.y).cross(&cam.ray_cam(b.x, b.y)).normalize();
            lines.push(ImageLine { a, b, normal });
        }
        (edges, lines)
    }

    /// Stereo's depths for the edgels of `edges` along every camera-facing edge of `model` at
    /// `pose`, as a camera with a 0.1 m baseline and 900 px focal length would give them (4 mm
    /// of depth to the pixel of disparity at 0.9 m).
    pub fn model_depths(
        model: &MatcherModel,
        pose: &Isometry3<f64>,
        cam: &PinholeCamera,
        edges: &EdgeMap,
    ) -> EdgelDepths {
        let mut depths = EdgelDepths::new(edges);
        for (_, line) in model.lines.iter().enumerate().filter(|(k, _)| model.faces_camera(*k, pose)) {
            let (a3, b3) = (pose * line.a, pose * line.b);
            let (Some(a), Some(b)) = (cam.project_cam(&a3), cam.project_cam(&b3)) else { continue };
            let steps = ((b - a).norm() as usize).max(1);
            for s in 0..=steps {
                let f = s as f64 / steps as f64;
                let (q, z) = (a + (b - a) * f, (a3 + (b3 - a3) * f).z);
                let (x, y) = (q.x.round() as usize, q.y.round() as usize);
                if let Some(i) = (x < edges.width && y < edges.height).then(|| edges.edgel_at(x, y)).flatten() {
                    depths.insert(i as usize, z, z * z / (900.0 * 0.1));
                }
            }
        }
        depths
    }
}

#[cfg(test)]
mod tests;
