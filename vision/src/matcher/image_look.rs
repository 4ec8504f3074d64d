//! The image look: parts lying flat on the table that stereo gave no 3D line to seed from,
//! found from two image lines meeting at a corner, the table, and both images.
//!
//! Where stereo lifts none of a part's edges (its edges near the rasters' direction, or its
//! silhouette matched to other edges in the right image), every other look is blind to it; yet
//! the left image may show its whole outline (under the side light, `side_light.toml` seeds
//! 1-200: five parts missed on no 3D line at all, their true poses running along edgels for
//! 77-100% of their wireframes). A part lying flat on the table has three degrees of freedom
//! left; a corner of the image where two image lines meet fixes them, given which
//! model corner it is and which face the part rests on: the corner lies on its ray at the
//! model corner's height above the top, and the model edge leaving it lies level in the plane
//! of the first image line, which fixes the turn about the table's normal. The second image
//! line must then run along the corner's other edge. Such a pose rests on no 3D evidence, so it
//! is fitted to both images' edgels at once ([`super::polish::polished`]), laid flat again, and
//! must be borne out by both images: [`MIN_IMAGE_SUPPORT`] of the part in view in each, which
//! a part read where another's edges happen to meet rarely is in both views.
//!
//! The image lines are all the left image's, lifted to 3D or not (where the lift went wrong the
//! outline is still there: lifted lines added 0.12 / 0.36 / 0.43 points below), but for those
//! the objects located already explain.
//!
//! On the tuning seeds (`marvin eval locate`, `widgets.toml` 1-500, `dense.toml` and
//! `side_light.toml` 1-200) this located 98.18 / 91.60 / 94.68% -> 98.35 / 92.53 / 95.61%,
//! with 5 / 13 / 2 -> 5 / 14 / 2 false reports (the one more an L-bracket read turned over
//! beside one, 13 mm and 179 deg off it, `dense.toml` seed 199). [`MIN_IMAGE_SUPPORT`] was set once, as the second
//! look's bar for a pose on one 3D line, not tuned; [`MIN_IMAGE_SUPPORT_TO_REFINE`] was chosen
//! there: 0.6 located 98.30 / 92.13 / 95.54% with 5 / 14 / 2 false reports, 0.5 98.33 / 92.46 /
//! 95.61% with the same (both with corners of 4 px).

use super::contrast::Shown;
use super::image_fit::View;
use super::model::{FlatCorner, FlatCorners, Located, MatchParams, MatcherModel, Seg, Table, eye_of};
use super::occlusion::{MIN_IN_VIEW, Solid};
use super::support::support;
use super::table::rests_flat;
use super::table_look::{REST_M, laid_flat};
use super::verify::{Explained, ImageEvidence, MAX_EXPLAINED, image_support_shown, image_support_shown_at_least};
use nalgebra::{Isometry3, Matrix3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// Two image lines' ends this close (pixels) meet at a corner, which lies where the lines
/// cross, no further than this from either end. As the second look's; on the tuning seeds 4 px
/// found 1 / 2 / 0 objects fewer (`widgets.toml` / `dense.toml` / `side_light.toml`), the same
/// false reports.
const CORNER_PX: f64 = 8.0;
/// Image lines meeting at a corner make at least this angle (radians), as the second look's
/// corners do.
const MIN_CORNER_RAD: f64 = 0.35;
/// The corner's other model edge must image within this angle (radians) of the second line.
const ALONG_RAD: f64 = 0.05;
/// A pose from the image look must run along edgels for this share of the part in view, in
/// each image.
pub(crate) const MIN_IMAGE_SUPPORT: f64 = 0.85;
/// A pose is fitted to the images if this much of it already runs along the left's edgels,
/// and of what the objects located leave of it in view along the right's (the fit is dear).
const MIN_IMAGE_SUPPORT_TO_REFINE: f64 = 0.5;
/// A corner whose edges both lie level must make the angle the image lines' level directions
/// make within this (radians) before its pose is worked out: a loose test, before the other
/// edge's image is held to [`ALONG_RAD`].
const LEVEL_TURN_RAD: f64 = 0.15;
/// The corner's other model edge, turned, must lie this near the plane of the other image line
/// (the cosine of its angle to the plane's normal) before its image is worked out.
const IN_PLANE: f64 = 0.1;
/// Of a part's wireframe in view, at least this share must be edges the light lets show
/// ([`super::contrast`]) for the rest to judge it.
const MIN_SHOWN: f64 = 0.5;
/// An image line another object's edges explain for more than this share is no part's corner.
const MAX_LINE_EXPLAINED: f64 = 0.5;

/// Where two image lines meet: the crossing point and, for each line, its end away from it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct ImageCorner {
    at: Point2<f64>,
    far: [Point2<f64>; 2],
    normals: [Vector3<f64>; 2],
}

/// The corners where two of `ev`'s image lines (those the `explained` edges do not account for)
/// meet end to end.
pub(crate) fn image_corners(ev: &ImageEvidence, explained: &Explained) -> Vec<ImageCorner> {
    let lines: Vec<&super::verify::ImageLine> = ev.lines.iter().chain(ev.lifted.iter()).collect();
    // Whether each line is another object's, asked only of lines that meet another (the
    // dearer test).
    let mut unexplained: Vec<Option<bool>> = vec![None; lines.len()];
    let mut out = Vec::new();
    for (i, li) in lines.iter().enumerate() {
        for (k, lk) in lines.iter().enumerate().skip(i + 1) {
            let (di, dk) = ((li.b - li.a).normalize(), (lk.b - lk.a).normalize());
            if di.dot(&dk).abs() > MIN_CORNER_RAD.cos() {
                continue;
            }
            let Some(at) = crossing(&li.a, &di, &lk.a, &dk) else { continue };
            let near_end = |a: &Point2<f64>, b: &Point2<f64>| {
                let (da, db) = ((a - at).norm(), (b - at).norm());
                (da.min(db) <= CORNER_PX).then_some(if da < db { *b } else { *a })
            };
            let (Some(far_i), Some(far_k)) = (near_end(&li.a, &li.b), near_end(&lk.a, &lk.b)) else { continue };
            let mut free = |j: usize| {
                *unexplained[j].get_or_insert_with(|| explained.share_of_line(lines[j]) <= MAX_LINE_EXPLAINED)
            };
            if free(i) && free(k) {
                out.push(ImageCorner { at, far: [far_i, far_k], normals: [li.normal, lk.normal] });
            }
        }
    }
    out
}

/// Where the line through `p` along `d` crosses the one through `q` along `e`.
fn crossing(
    p: &Point2<f64>,
    d: &nalgebra::Vector2<f64>,
    q: &Point2<f64>,
    e: &nalgebra::Vector2<f64>,
) -> Option<Point2<f64>> {
    let den = d.x * e.y - d.y * e.x;
    if den.abs() < 1e-9 {
        return None;
    }
    let w = q - p;
    Some(p + d * ((w.x * e.y - w.y * e.x) / den))
}

fn flat_corners(model: &MatcherModel, up: &Vector3<f64>) -> Vec<FlatCorner> {
    let mut out = Vec::new();
    for n in &model.resting {
        let lay = super::table::turn_between(n, &-up);
        let lowest = model.corners.iter().map(|c| n.dot(&c.coords)).fold(f64::MIN, f64::max);
        for c in model.corner_edges.iter().filter(|c| c.out.dot(n).abs() < 1e-6) {
            let height = lowest - n.dot(&c.corner.coords);
            let out_len = model.lines[c.line].len;
            let (out_dir, other) = (lay * c.out, lay * c.other_out);
            let level_turn =
                (other.dot(up).abs() < 1e-6).then(|| (out_dir.dot(&other), up.dot(&out_dir.cross(&other))));
            let upright = (other.dot(up).abs() > 1.0 - 1e-9).then(|| other.dot(up).signum());
            let other_local = Vector3::new(out_dir.dot(&other), up.cross(&out_dir).dot(&other), up.dot(&other));
            let corner = c.clone();
            let shape = 0; // numbered with the others' in `FlatCorners::new`
            out.push(FlatCorner {
                corner,
                lay,
                out: out_dir,
                out_len,
                height,
                level_turn,
                upright,
                other_local,
                shape,
            });
        }
    }
    out
}

/// Numbers each of `all`'s distinct shapes (height, edge lengths, the other edge in the level
/// edge's frame, alike within a nanometre), in order of first appearance; returns how many.
fn number_shapes(all: &mut [FlatCorner]) -> usize {
    let key =
        |f: &FlatCorner| [f.height, f.out_len, f.corner.other_len, f.other_local.x, f.other_local.y, f.other_local.z];
    let mut shapes: Vec<[f64; 6]> = Vec::new();
    for f in all.iter_mut() {
        let k = key(f);
        f.shape = match shapes.iter().position(|s| s.iter().zip(&k).all(|(a, b)| (a - b).abs() < 1e-9)) {
            Some(i) => i,
            None => {
                shapes.push(k);
                shapes.len() - 1
            }
        };
    }
    shapes.len()
}

/// `model`'s flat corners on a table whose normal is `up` (`cam`), made on the first look and
/// kept with the model for that table (the cameras do not move between scenes); made afresh,
/// not kept, for another.
fn flat_corners_of<'m>(model: &'m MatcherModel, up: &Vector3<f64>) -> std::borrow::Cow<'m, FlatCorners> {
    let (kept_for, flat) = model.flat_corners.get_or_init(|| (*up, FlatCorners::new(flat_corners(model, up))));
    if kept_for == up {
        std::borrow::Cow::Borrowed(flat)
    } else {
        std::borrow::Cow::Owned(FlatCorners::new(flat_corners(model, up)))
    }
}

impl FlatCorners {
    fn new(mut all: Vec<FlatCorner>) -> FlatCorners {
        let shapes = number_shapes(&mut all);
        let (mut level, mut upright, mut other) = (Vec::new(), [Vec::new(), Vec::new()], Vec::new());
        for (i, f) in all.iter().enumerate() {
            match (f.level_turn, f.upright) {
                (Some((cos, sin)), _) => level.push((sin.atan2(cos), i)),
                (None, Some(sign)) => upright[usize::from(sign < 0.0)].push(i),
                (None, None) => other.push(i),
            }
        }
        level.sort_by(|a, b| a.0.total_cmp(&b.0));
        FlatCorners { all, level, upright, other, shapes }
    }

    /// The corners that may fit `edge`: those whose level angle lies within [`LEVEL_TURN_RAD`]
    /// of the image corner's (all of them where it has none), the upright ones that stand the
    /// way its other line runs, and those with neither.
    fn for_edge<'a>(&'a self, edge: &LevelEdge) -> impl Iterator<Item = &'a FlatCorner> {
        use std::f64::consts::{PI, TAU};
        let (first, second) = match edge.level_turn {
            None => (&self.level[..], &self.level[..0]),
            Some((cos, sin)) => {
                // Widened by a hair: `LevelEdge::corner_at` holds them to the tolerance exactly.
                let (at, reach) = (sin.atan2(cos), LEVEL_TURN_RAD + 1e-9);
                let (lo, hi) = (at - reach, at + reach);
                if lo < -PI {
                    (self.between(lo + TAU, PI), self.between(-PI, hi))
                } else if hi > PI {
                    (self.between(lo, PI), self.between(-PI, hi - TAU))
                } else {
                    (self.between(lo, hi), &self.level[..0])
                }
            }
        };
        let upright = edge.upright.map_or(&[][..], |sign| &self.upright[usize::from(sign < 0.0)][..]);
        let level = first.iter().chain(second).map(|&(_, i)| i);
        level.chain(upright.iter().copied()).chain(self.other.iter().copied()).map(|i| &self.all[i])
    }

    /// The level corners whose angle lies within `lo`..=`hi`.
    fn between(&self, lo: f64, hi: f64) -> &[(f64, usize)] {
        let (from, to) = (self.level.partition_point(|(a, _)| *a < lo), self.level.partition_point(|(a, _)| *a <= hi));
        &self.level[from..to.max(from)]
    }
}

/// An image corner with one of its lines taken for a level model edge: the ray through the
/// corner, and the level direction in that line's plane that images along it, out of the corner.
struct LevelEdge<'i> {
    ic: &'i ImageCorner,
    first: usize,
    ray: Vector3<f64>,
    dir: Vector3<f64>,
    /// The cosine and sine of the turn about the table's normal from `dir` to the level
    /// direction in the other line's plane that images along it: what a corner whose edges
    /// both lie level must turn by.
    level_turn: Option<(f64, f64)>,
    /// Whether the other line runs up (1) or down (-1) the table's normal, as an edge standing
    /// on the table at the corner would image, if it does.
    upright: Option<f64>,
}

impl<'i> LevelEdge<'i> {
    fn new(ic: &'i ImageCorner, first: usize, up: &Vector3<f64>, ev: &ImageEvidence) -> Option<LevelEdge<'i>> {
        let ray = ev.cam.ray_cam(ic.at.x, ic.at.y);
        // The level direction in line `k`'s plane, the way it images along the line. (Which
        // way it images does not depend on how far along the ray.)
        let level = |k: usize| {
            let level = ic.normals[k].cross(up);
            if level.norm() < 1e-9 {
                return None;
            }
            let dir = level.normalize();
            let step = ev.cam.project_cam(&Point3::from(ray + dir * 0.01))? - ev.cam.project_cam(&Point3::from(ray))?;
            Some(if step.dot(&(ic.far[k] - ic.at)) < 0.0 { -dir } else { dir })
        };
        let dir = level(first)?;
        let level_turn = level(1 - first).map(|other| (dir.dot(&other), up.dot(&dir.cross(&other))));
        // An upright edge images towards the normal's vanishing point whatever its height.
        let line = ic.far[1 - first] - ic.at;
        let upward = ev.cam.project_cam(&Point3::from(ray + up * 0.01))? - ev.cam.project_cam(&Point3::from(ray))?;
        let cos = upward.dot(&line) / (upward.norm() * line.norm()).max(1e-12);
        let upright = (cos.abs() >= ALONG_RAD.cos()).then_some(cos.signum());
        Some(LevelEdge { ic, first, ray, dir, level_turn, upright })
    }

    /// Where `f`'s corner lies if a part resting on `table` shows it here: on the ray, at the
    /// corner's height, its level edge along this one; `None` where the ray misses that height
    /// or the corner's other edge does not image along the corner's other line, out of the
    /// corner and at least as long. Only `f`'s shape counts ([`FlatCorner::other_local`]).
    fn corner_at(&self, f: &FlatCorner, table: &Table, ev: &ImageEvidence) -> Option<Point3<f64>> {
        // A corner whose edges lie level makes the same angle on the table as the image lines'
        // level directions do, wherever it lies: the cheapest test, first.
        if let (Some((c, s)), Some((ci, si))) = (f.level_turn, self.level_turn)
            && c * ci + s * si < LEVEL_TURN_RAD.cos()
        {
            return None;
        }
        if f.upright.is_some() && f.upright != self.upright {
            return None;
        }
        let up = Vector3::from(table.up);
        // The other edge with the level edge turned onto `dir`; it must lie near the other
        // line's plane (a cheap test first).
        let other = self.dir * f.other_local.x + up.cross(&self.dir) * f.other_local.y + up * f.other_local.z;
        if self.ic.normals[1 - self.first].dot(&other).abs() > IN_PLANE {
            return None;
        }
        let s = (f.height - table.camera_height_m) / up.dot(&self.ray);
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        let at = Point3::from(self.ray * s);
        // Each image line is some stretch of its edge: no longer than the edge's image.
        let first = ev.cam.project_cam(&(at + self.dir * f.out_len))? - self.ic.at;
        if (self.ic.far[self.first] - self.ic.at).norm() > first.norm() + CORNER_PX {
            return None;
        }
        let edge = ev.cam.project_cam(&(at + other * f.corner.other_len))? - self.ic.at;
        let line = self.ic.far[1 - self.first] - self.ic.at;
        if edge.dot(&line) < ALONG_RAD.cos() * edge.norm() * line.norm() || line.norm() > edge.norm() + CORNER_PX {
            return None;
        }
        Some(at)
    }

    /// [`Self::corner_at`], asked once for each of the model's corner shapes: `seen` holds
    /// what it said for each shape so far with this edge.
    fn corner_at_memo(
        &self,
        f: &FlatCorner,
        (table, ev): (&Table, &ImageEvidence),
        seen: &mut [Option<Option<Point3<f64>>>],
    ) -> Option<Point3<f64>> {
        *seen[f.shape].get_or_insert_with(|| self.corner_at(f, table, ev))
    }

    /// The pose that rests `f`'s face on the table (normal `up`) with its corner `at` and its
    /// level edge along this one.
    fn pose(&self, f: &FlatCorner, at: &Point3<f64>, up: &Vector3<f64>) -> Isometry3<f64> {
        // The turn about the normal taking the level edge onto `dir`, by its cosine and sine.
        let (cos, sin) = (f.out.dot(&self.dir), up.dot(&f.out.cross(&self.dir)));
        let yaw = Matrix3::identity() * cos + up.cross_matrix() * sin + up * up.transpose() * (1.0 - cos);
        let rotation = Rotation3::from_matrix_unchecked(yaw) * f.lay;
        let rotation = UnitQuaternion::from_rotation_matrix(&rotation);
        Isometry3::from_parts(Translation3::from(at.coords - rotation * f.corner.corner.coords), rotation)
    }
}

/// The objects located so far as solids in each camera's frame (left, then right): what may
/// hide a part from each. Made when first asked for: most scenes leave the image look no pose
/// to fit.
pub(crate) struct LocatedSolids<'a> {
    models: &'a [MatcherModel],
    kept: &'a [Located],
    right_from_cam: Isometry3<f64>,
    solids: std::sync::OnceLock<[Vec<Solid>; 2]>,
}

impl<'a> LocatedSolids<'a> {
    pub(crate) fn new(models: &'a [MatcherModel], kept: &'a [Located], ev: &ImageEvidence) -> LocatedSolids<'a> {
        let right_from_cam = ev.right.as_ref().map_or(Isometry3::identity(), |r| r.right_from_cam);
        LocatedSolids { models, kept, right_from_cam, solids: std::sync::OnceLock::new() }
    }

    fn get(&self) -> &[Vec<Solid>; 2] {
        self.solids.get_or_init(|| {
            let in_frame = |from_left: &Isometry3<f64>| {
                self.kept
                    .iter()
                    .filter_map(|l| {
                        let model = self.models.iter().find(|m| m.name == l.model)?;
                        Some(Solid::new(model, &(from_left * l.cam_from_model)))
                    })
                    .collect()
            };
            [in_frame(&Isometry3::identity()), in_frame(&self.right_from_cam)]
        })
    }
}

/// At most one object of `model` lying flat on the table, from `image_corners`, on the lines
/// not `claimed`, with the `located` objects' solids (in each camera's frame) hiding what lies
/// behind them and the `explained` image edges counting for none of it, judged on the edges
/// the light lets show where `shown` says which ([`super::contrast`]); and the starts given up
/// for want of edgels, to be judged again by the light ([`rejudge`]). Nothing without the
/// table or the right image.
pub(crate) fn locate(
    model: &MatcherModel,
    (scene, claimed): (&[Seg], &[bool]),
    p: &MatchParams,
    ev: &ImageEvidence,
    (image_corners, located, explained): (&[ImageCorner], &LocatedSolids, &Explained),
    shown: Option<&Shown>,
) -> (Option<Located>, Vec<Isometry3<f64>>) {
    let mut faint = Vec::new();
    let (Some(table), Some(right)) = (p.table.as_ref(), ev.right.as_deref()) else { return (None, faint) };
    if image_corners.is_empty() {
        return (None, faint);
    }
    let look = Look { model, table, views: views_of(ev, right), located, explained, shown };
    let up = Vector3::from(table.up);
    let flat = flat_corners_of(model, &up);
    let mut best: Option<(f64, Isometry3<f64>)> = None;
    let mut tried: Vec<Isometry3<f64>> = Vec::new();
    let edges = image_corners.iter().flat_map(|ic| (0..2).filter_map(move |first| LevelEdge::new(ic, first, &up, ev)));
    let mut shapes_seen = vec![None; flat.shapes];
    for edge in edges {
        shapes_seen.fill(None);
        for f in flat.for_edge(&edge) {
            let Some(at) = edge.corner_at_memo(f, (table, ev), &mut shapes_seen) else { continue };
            let start = edge.pose(f, &at, &up);
            let eye = eye_of(&start);
            if !model.may_be_seen(f.corner.line, &eye) || !model.may_be_seen(f.corner.other, &eye) {
                continue;
            }
            match look.judge(&start, &mut tried) {
                Judged::Seen(seen, pose) if best.is_none_or(|(b, _)| seen > b) => best = Some((seen, pose)),
                Judged::Faint => faint.push(start),
                _ => {}
            }
        }
    }
    (best.map(|best| located_at(model, (scene, claimed), p, best)), faint)
}

/// The image look's `faint` starts of `model` (those [`locate`] gave up on for want of
/// edgels) judged again on the edges the light lets show. The caller passes only those with
/// an edge the light leaves dim: the others would fare as they did.
pub(crate) fn rejudge(
    model: &MatcherModel,
    (scene, claimed): (&[Seg], &[bool]),
    p: &MatchParams,
    ev: &ImageEvidence,
    (faint, located, explained): (&[Isometry3<f64>], &LocatedSolids, &Explained),
    shown: &Shown,
) -> Option<Located> {
    let (table, right) = (p.table.as_ref()?, ev.right.as_deref()?);
    let look = Look { model, table, views: views_of(ev, right), located, explained, shown: Some(shown) };
    let mut best: Option<(f64, Isometry3<f64>)> = None;
    let mut tried: Vec<Isometry3<f64>> = Vec::new();
    for start in faint {
        if let Judged::Seen(seen, pose) = look.judge(start, &mut tried)
            && best.is_none_or(|(b, _)| seen > b)
        {
            best = Some((seen, pose));
        }
    }
    best.map(|best| located_at(model, (scene, claimed), p, best))
}

/// The pair's two images as the stereo fit takes them: the left, and the right where it sits.
fn views_of<'a>(ev: &'a ImageEvidence<'a>, right: &'a super::verify::RightImage<'a>) -> [View<'a>; 2] {
    [View { ev, cam_from_left: Isometry3::identity() }, View { ev: &right.ev, cam_from_left: right.right_from_cam }]
}

/// What the image look judges a start by.
struct Look<'l> {
    model: &'l MatcherModel,
    table: &'l Table,
    views: [View<'l>; 2],
    located: &'l LocatedSolids<'l>,
    explained: &'l Explained,
    shown: Option<&'l Shown>,
}

/// What became of a start.
enum Judged {
    /// Fitted, it runs along edgels in both images for this share of what is in view.
    Seen(f64, Isometry3<f64>),
    /// Too few edgels along it in an image, before or after the fit.
    Faint,
    /// Fitted where another start was, off the table, or on edges others explain.
    Not,
}

impl Look<'_> {
    /// `start` checked on both images, fitted to them, laid flat and checked again (`tried`
    /// holds the poses fitted so far, each judged once).
    fn judge(&self, start: &Isometry3<f64>, tried: &mut Vec<Isometry3<f64>>) -> Judged {
        let (model, [left, right]) = (self.model, &self.views);
        // Both images must show enough of the start before it is fitted to them (the fit is
        // dear, and a start from where other edges meet rarely shows in both).
        let dim = self.shown.map(|s| s.dim_lines(model, start)).unwrap_or_default();
        if image_support_shown_at_least(model, start, left.ev, MIN_IMAGE_SUPPORT_TO_REFINE, &dim).is_none() {
            return Judged::Faint;
        }
        let solids = self.located.get();
        let in_right = right.cam_from_left * start;
        let own = Solid::new(model, &in_right);
        let hiding: Vec<&Solid> = solids[1].iter().chain([&own]).collect();
        if image_support_shown(model, &in_right, right.ev, &hiding, &dim).0 < MIN_IMAGE_SUPPORT_TO_REFINE {
            return Judged::Faint;
        }
        let others: Vec<Vec<&Solid>> = solids.iter().map(|s| s.iter().collect()).collect();
        let pose = laid_flat(self.table, model, &super::polish::polished(model, start, &others, &self.views, None));
        if tried.iter().any(|t| super::table_look::same_place(t, &pose)) {
            return Judged::Not;
        }
        tried.push(pose);
        if !rests_flat(self.table, model, &pose, REST_M) {
            return Judged::Not;
        }
        let dim = self.shown.map(|s| s.dim_lines(model, &pose)).unwrap_or_default();
        let Some(seen) = seen_in_both(model, &pose, &self.views, solids, &dim) else { return Judged::Faint };
        if self.explained.share(model, &pose, left.ev.cam) > MAX_EXPLAINED {
            return Judged::Not;
        }
        Judged::Seen(seen, pose)
    }
}

/// The report of `model` at `pose`, seen along edgels for `seen` of what is in view, with the
/// 3D lines not `claimed` that it lies along.
fn located_at(
    model: &MatcherModel,
    (scene, claimed): (&[Seg], &[bool]),
    p: &MatchParams,
    (seen, pose): (f64, Isometry3<f64>),
) -> Located {
    let free: Vec<bool> = claimed.iter().map(|c| !c).collect();
    let (score, pairs) = support(model, &pose, scene, &free, p);
    super::ranking::Candidate { pose, score, pairs, image_support: seen }.located(model, seen)
}

/// The lesser of the shares of the part in view that run along edgels in the two images, if
/// both reach [`MIN_IMAGE_SUPPORT`] and enough of the part is in view in each.
fn seen_in_both(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    views: &[View; 2],
    solids: &[Vec<Solid>; 2],
    dim: &[bool],
) -> Option<f64> {
    let mut least = f64::MAX;
    for (v, in_view) in views.iter().zip(solids) {
        let at = v.cam_from_left * pose;
        let own = Solid::new(model, &at);
        let hiding: Vec<&Solid> = in_view.iter().chain([&own]).collect();
        let (seen, share, bright) = image_support_shown(model, &at, v.ev, &hiding, dim);
        if seen < MIN_IMAGE_SUPPORT || share < MIN_IN_VIEW || bright < MIN_SHOWN {
            return None;
        }
        least = least.min(seen);
    }
    Some(least)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::canny::EdgeMap;
    use crate::matcher::fixtures::{model, verged_pair};
    use crate::matcher::model::Corner;
    use crate::matcher::verify::{RightImage, drawn::model_edges};

    /// A block lying flat on the table (the world's z = 0), its camera-facing edges drawn in both
    /// images of a verged pair and its image lines in the left, but no 3D line at all.
    struct Scene {
        block: MatcherModel,
        truth: Isometry3<f64>,
        cams: (mesh::PinholeCamera, mesh::PinholeCamera),
        table: Table,
    }

    fn scene() -> Scene {
        let block = model("block");
        let cams = verged_pair();
        let lowest = block.corners.iter().map(|c| c.z).fold(f64::MAX, f64::min);
        let world_from_model = Isometry3::from_parts(
            Translation3::new(0.02, -0.03, -lowest),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
        );
        let truth = cams.0.cam_from_world() * world_from_model;
        let table = Table::from_cam_from_table(&cams.0.cam_from_world());
        Scene { block, truth, cams, table }
    }

    /// The image look on `s`, the right image showing the block at `right_pose` (`cam` frame).
    fn look(s: &Scene, right_pose: &Isometry3<f64>) -> Option<Located> {
        let (left, right) = &s.cams;
        let right_from_cam = right.cam_from_world() * left.world_from_cam;
        let (left_edges, lines) = model_edges(&s.block, &s.truth, left);
        let (right_edges, _) = model_edges(&s.block, &(right_from_cam * right_pose), right);
        let ev = ImageEvidence::new(left, &left_edges, lines)
            .with_right(RightImage { ev: ImageEvidence::new(right, &right_edges, Vec::new()), right_from_cam });
        let p = MatchParams { table: Some(s.table), ..MatchParams::default() };
        let explained = Explained::of(std::iter::empty(), left);
        let corners = image_corners(&ev, &explained);
        assert!(!corners.is_empty(), "the block's outline meets at corners");
        let located = LocatedSolids::new(&[], &[], &ev);
        locate(&s.block, (&[], &[]), &p, &ev, (&corners, &located, &explained), None).0
    }

    /// Found from the image corners alone, the block comes out where it lies, within a fraction
    /// of a millimetre and degree (up to its symmetry: on its lines), with no 3D support.
    #[test]
    fn a_part_flat_on_the_table_is_found_from_the_corners_of_both_images() {
        let s = scene();
        let found = look(&s, &s.truth).expect("the block");
        assert!(crate::matcher::fixtures::on_its_lines(&s.block, &found.cam_from_model, &s.truth, 5e-4));
        assert_eq!(found.support, 0.0);
        assert!(found.image_support >= MIN_IMAGE_SUPPORT);
    }

    /// A light from behind the block and above, the one that [`side_lit`] draws by.
    fn light_from_behind(s: &Scene) -> super::super::light::Light {
        let towards = s.cams.0.cam_from_world().rotation * Vector3::new(0.2, 1.0, 1.0).normalize();
        super::super::light::Light { ambient: 0.2 * 255.0, towards_light: towards * 0.8 * 255.0 }
    }

    /// Both images of `s`'s block drawn by ray casting under [`light_from_behind`], on a table
    /// of the grey the light gives its camera-facing sides (which it leaves in shadow): Canny's
    /// edgels in each, the left image's lines along the block's edges that its edgels show,
    /// and the table's grey.
    fn side_lit(s: &Scene) -> (EdgeMap, EdgeMap, Vec<super::super::verify::ImageLine>, f64) {
        use crate::front_end::canny::{CannyParams, canny};
        let (left, right) = &s.cams;
        let right_from_cam = right.cam_from_world() * left.world_from_cam;
        let light = light_from_behind(s);
        let table_grey = (crate::matcher::fixtures::albedo(&s.block.name) * light.ambient).round();
        let draw = |cam: &mesh::PinholeCamera, from_left: Isometry3<f64>| {
            let l = super::super::light::Light { towards_light: from_left.rotation * light.towards_light, ..light };
            let image = crate::matcher::fixtures::render(
                cam,
                &[(&s.block, from_left * s.truth)],
                &|n| l.predict(n),
                table_grey as u8,
            );
            canny(&image, &CannyParams::default())
        };
        let (left_edges, right_edges) = (draw(left, Isometry3::identity()), draw(right, right_from_cam));
        let shows = |l: &super::super::verify::ImageLine| {
            let ev = ImageEvidence::new(left, &left_edges, Vec::new());
            let dir = (l.b - l.a).normalize();
            let samples = 20;
            let seen = (1..samples)
                .filter(|k| {
                    let q = l.a + (l.b - l.a) * (*k as f64 / samples as f64);
                    ev.edgel_near(q.x, q.y, dir).is_some()
                })
                .count();
            seen * 5 >= (samples - 1) * 4
        };
        let lines = model_edges(&s.block, &s.truth, left).1.into_iter().filter(shows).collect();
        (left_edges, right_edges, lines, table_grey)
    }

    /// Under a light that leaves its camera-facing sides the table's grey, a block lying flat
    /// shows its top's outline alone. Held to all of its outline the image look gives it up
    /// for want of edgels; judged again on the edges the light lets show, it is found where it
    /// lies.
    #[test]
    fn a_part_whose_sides_show_the_tables_grey_is_found_on_the_edges_the_light_lets_show() {
        let s = scene();
        let (left_edges, right_edges, lines, table_grey) = side_lit(&s);
        let (left, right) = &s.cams;
        let right_from_cam = right.cam_from_world() * left.world_from_cam;
        // The light as the image shows it on the block: its material's share of the drawing light.
        let (light, albedo) = (light_from_behind(&s), crate::matcher::fixtures::albedo(&s.block.name));
        let seen =
            super::super::light::Light { ambient: albedo * light.ambient, towards_light: albedo * light.towards_light };
        let shown = Shown { light: seen, table_grey };
        let dim = shown.dim_lines(&s.block, &s.truth);
        let facing = (0..s.block.lines.len()).filter(|k| s.block.faces_camera(*k, &s.truth)).count();
        assert!(lines.len() < facing, "{} of the block's {facing} edges show", lines.len());
        assert_eq!(dim.iter().filter(|d| **d).count(), facing - lines.len(), "the dim edges are those not shown");
        let ev = ImageEvidence::new(left, &left_edges, lines)
            .with_right(RightImage { ev: ImageEvidence::new(right, &right_edges, Vec::new()), right_from_cam });
        let p = MatchParams { table: Some(s.table), ..MatchParams::default() };
        let explained = Explained::of(std::iter::empty(), left);
        let corners = image_corners(&ev, &explained);
        let located = LocatedSolids::new(&[], &[], &ev);
        let (found, faint) = locate(&s.block, (&[], &[]), &p, &ev, (&corners, &located, &explained), None);
        assert!(found.is_none(), "held to its whole outline");
        assert!(!faint.is_empty());
        let found = rejudge(&s.block, (&[], &[]), &p, &ev, (&faint, &located, &explained), &shown).expect("the block");
        assert!(crate::matcher::fixtures::on_its_lines(&s.block, &found.cam_from_model, &s.truth, 5e-4));
    }

    /// A flat corner's shape is all its test sees, and its pose puts it where the test looked:
    /// the pose takes the model corner onto the point found, the level edge along the image
    /// line's level direction and the other edge along the direction the test held to the
    /// other line; and every corner of one shape has that shape's height and edge lengths.
    #[test]
    fn a_flat_corners_pose_shows_its_shape_where_the_test_looked() {
        let up = Vector3::new(0.1, -0.6, -0.79).normalize();
        let dir = up.cross(&Vector3::x()).normalize();
        let ic = ImageCorner { at: Point2::origin(), far: [Point2::origin(); 2], normals: [Vector3::x(); 2] };
        let edge = LevelEdge { ic: &ic, first: 0, ray: Vector3::z(), dir, level_turn: None, upright: None };
        let at = Point3::new(0.02, -0.01, 0.7);
        for name in ["widget", "wedge", "hex_prism", "u_channel", "l_bracket"] {
            let m = model(name);
            let flat = FlatCorners::new(flat_corners(&m, &up));
            assert!(flat.shapes < flat.all.len(), "{name}: {} shapes of {} corners", flat.shapes, flat.all.len());
            let first_of_shape = |k: usize| flat.all.iter().find(|f| f.shape == k).unwrap();
            for f in &flat.all {
                let pose = edge.pose(f, &at, &up);
                let local = f.other_local;
                let other = dir * local.x + up.cross(&dir) * local.y + up * local.z;
                assert!((pose * f.corner.corner - at).norm() < 1e-9, "{name}: the corner where it was looked for");
                assert!((pose.rotation * f.corner.out - dir).norm() < 1e-6, "{name}: the level edge along the line");
                assert!((pose.rotation * f.corner.other_out - other).norm() < 1e-6, "{name}: the other edge as tested");
                let like = first_of_shape(f.shape);
                let lengths =
                    [f.height - like.height, f.out_len - like.out_len, f.corner.other_len - like.corner.other_len];
                assert!(lengths.iter().all(|d| d.abs() < 1e-9) && (f.other_local - like.other_local).norm() < 1e-9);
            }
        }
    }

    /// The corners tried against an image corner are exactly those whose level angle and
    /// upright edge the image corner allows (the tests `LevelEdge::corner_at` makes first), for
    /// models lying on every face, at image corners of every angle and either upright way.
    #[test]
    fn each_image_corner_is_tried_against_the_corners_that_may_fit_it() {
        let up = Vector3::new(0.1, -0.6, -0.79).normalize();
        let ic = ImageCorner { at: Point2::origin(), far: [Point2::origin(); 2], normals: [Vector3::x(); 2] };
        for name in ["widget", "wedge", "hex_prism", "u_channel"] {
            let m = model(name);
            let flat = FlatCorners::new(flat_corners(&m, &up));
            for k in 0..64 {
                let angle = -std::f64::consts::PI + k as f64 * 0.1;
                let turn = Some((angle.cos(), angle.sin()));
                for (level_turn, upright) in [(turn, None), (None, Some(1.0)), (turn, Some(-1.0))] {
                    let edge =
                        LevelEdge { ic: &ic, first: 0, ray: Vector3::z(), dir: Vector3::x(), level_turn, upright };
                    let allowed = |f: &FlatCorner| {
                        let level = match (f.level_turn, edge.level_turn) {
                            (Some((c, s)), Some((ci, si))) => c * ci + s * si >= LEVEL_TURN_RAD.cos(),
                            _ => true,
                        };
                        level && (f.upright.is_none() || f.upright == edge.upright)
                    };
                    let key = |f: &FlatCorner| (f.corner.line, f.corner.other, f.height.to_bits(), f.out.x.to_bits());
                    let mut tried: Vec<_> = flat.for_edge(&edge).filter(|f| allowed(f)).map(key).collect();
                    let mut want: Vec<_> = flat.all.iter().filter(|f| allowed(f)).map(key).collect();
                    tried.sort();
                    want.sort();
                    assert_eq!(tried, want, "{name} at {angle:.2}");
                }
            }
        }
    }

    /// Level angles either side of a half turn are found across it.
    #[test]
    fn level_angles_near_a_half_turn_are_found_across_it() {
        use std::f64::consts::PI;
        let corner = Corner {
            line: 0,
            other: 1,
            corner: Point3::origin(),
            out: Vector3::x(),
            other_out: Vector3::y(),
            other_len: 0.01,
        };
        let at = |angle: f64| FlatCorner {
            corner: corner.clone(),
            lay: Rotation3::identity(),
            out: Vector3::x(),
            out_len: 0.01,
            height: angle,
            level_turn: Some((angle.cos(), angle.sin())),
            upright: None,
            other_local: Vector3::y(),
            shape: 0,
        };
        let flat = FlatCorners::new([-3.1, -2.0, 0.0, 3.05].map(at).into());
        let ic = ImageCorner { at: Point2::origin(), far: [Point2::origin(); 2], normals: [Vector3::x(); 2] };
        let found = |angle: f64| {
            let level_turn = Some((angle.cos(), angle.sin()));
            let edge = LevelEdge { ic: &ic, first: 0, ray: Vector3::z(), dir: Vector3::x(), level_turn, upright: None };
            let mut heights: Vec<f64> = flat.for_edge(&edge).map(|f| f.height).collect();
            heights.sort_by(f64::total_cmp);
            heights
        };
        assert_eq!(found(PI - 0.01), [-3.1, 3.05]);
        assert_eq!(found(-PI + 0.01), [-3.1, 3.05]);
        assert_eq!(found(-2.1), [-2.0]);
        assert_eq!(found(1.0), Vec::<f64>::new());
    }

    /// The right image bears out no pose the left's corners give when it shows the block 1 cm
    /// further along the table: nothing is reported.
    #[test]
    fn a_part_the_right_image_does_not_show_is_not_reported() {
        let s = scene();
        let up = Vector3::from(s.table.up);
        let aside = up.cross(&Vector3::z()).normalize() * 0.01;
        assert!(look(&s, &(Translation3::from(aside) * s.truth)).is_none());
    }
}
