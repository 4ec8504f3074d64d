//! Pose refinement against the left image and the 3D lines together (or against both images
//! of the pair, [`refine_in_views`]): each camera-facing model
//! edge, sampled every few pixels, is pulled across its image onto the nearest edgel that runs
//! along it, and each supporting 3D line's ends onto their model line, by damped Gauss-Newton
//! on the six pose parameters.
//!
//! Poses from little 3D evidence (the second look's one 3D line and one image line) come out a
//! few degrees off, and a few degrees is enough for half the wireframe to miss its edgels: the
//! image check then rejects the right object. The image alone fixes depth poorly, which the 3D
//! lines supply.

use super::model::{MatcherModel, Seg};
use super::verify::{ALONG_RAD, ImageEvidence, looks_across};
use nalgebra::{
    Isometry3, Matrix2x3, Matrix6, Point2, Point3, Translation3, UnitQuaternion, Vector2, Vector3, Vector6,
};

/// Model edges are sampled every this many pixels of their image.
const SAMPLE_PX: f64 = 3.0;
/// Edgels are sought this far (pixels) either side of a sample, across the edge.
pub const SEARCH_PX: f64 = 6.0;
/// Residuals beyond this (pixels) are down-weighted (Huber).
const HUBER_PX: f64 = 1.5;
/// Gauss-Newton steps at most.
const ITERATIONS: usize = 8;
/// Steps of the looks' fit on one image small enough to stop at (radians, metres the part
/// moves): a hundredth of a millimetre, against pose errors near 0.1 mm that the stereo polish
/// then brings down. (A hundred times finer, as at first, took 6.5 steps a fit on `marvin bench
/// vision`'s scene against 5.3, for the same reports and pose medians on the tuning seeds.)
const LOOK_STOP: (f64, f64) = (1e-4, 1e-5);

/// The linearised residuals `row . delta = target` gathered as weighted normal equations
/// (`normal delta = rhs`), and how many there were.
struct Rows {
    /// Its lower triangle only, the part the Cholesky factorisation reads (the upper stays 0).
    normal: Matrix6<f64>,
    rhs: Vector6<f64>,
    count: usize,
}

impl Rows {
    fn new() -> Rows {
        Rows { normal: Matrix6::zeros(), rhs: Vector6::zeros(), count: 0 }
    }

    /// Adds `row . delta = target` with a Huber weight on `target` (in pixels).
    fn add(&mut self, row: Vector6<f64>, target: f64) {
        let w = if target.abs() <= HUBER_PX { 1.0 } else { HUBER_PX / target.abs() };
        // Term by term as `w * row * row.transpose()` works it out, below the diagonal only:
        // the rows are most of the image fits' arithmetic.
        let weighted = w * row;
        for j in 0..6 {
            for i in j..6 {
                self.normal[(i, j)] += weighted[i] * row[j];
            }
        }
        self.rhs += w * target * row;
        self.count += 1;
    }
}

/// The row for moving point `x` (cam frame) by a small turn `omega` and shift `tau`
/// (`x + omega x x + tau`) along `g`: `g . (omega x x + tau) = omega . (x x g) + tau . g`.
fn motion_row(x: &Point3<f64>, g: &Vector3<f64>) -> Vector6<f64> {
    let w = x.coords.cross(g);
    Vector6::new(w.x, w.y, w.z, g.x, g.y, g.z)
}

/// Offset (pixels, along `normal`) from `u` to the nearest edgel within `search` that runs
/// along `dir`. The search steps outwards from `u`, both ways by turns, and stops once no
/// pixel further out could hold a nearer edgel.
///
/// `bins` are `dir`'s orientation bins ([`ImageEvidence::bins_along`]) and `looks` the
/// search's stretch ([`looks_across`]): a sample with no edgel of those bins anywhere along its
/// search is passed over on a few look-ups of the mask. (A sample that finds no edgel steps
/// through every pixel of its search, 25 of them at [`SEARCH_PX`]: the fifth of the samples
/// that found none took half the steps.)
fn nearest_edgel_across(
    ev: &ImageEvidence,
    u: &Point2<f64>,
    (dir, bins): (&Vector2<f64>, u32),
    (search, looks): (f64, &[f64]),
) -> Option<f64> {
    let normal = Vector2::new(-dir.y, dir.x);
    if !ev.may_hold_across(u, &normal, looks, bins) {
        return None;
    }
    let steps = (2.0 * search) as i64;
    let cos_along = ALONG_RAD.cos();
    let mut best: Option<f64> = None;
    for k in 0..=steps {
        let reach = k as f64 * 0.5;
        // An edgel lies within 0.71 px of its pixel's centre.
        if best.is_some_and(|b| b.abs() < reach - 0.75) {
            break;
        }
        for offset in if k == 0 { [0.0, f64::NAN] } else { [reach, -reach] } {
            if offset.is_nan() {
                continue;
            }
            let q = u + normal * offset;
            let (px, py) = (crate::image::nearest_px(q.x), crate::image::nearest_px(q.y));
            if px < 0 || py < 0 || px >= ev.edges.width as i64 || py >= ev.edges.height as i64 {
                continue;
            }
            let (px, py) = (px as usize, py as usize);
            if !ev.occupied(py * ev.edges.width + px) {
                continue;
            }
            let Some(i) = ev.edges.edgel_at(px, py) else { continue };
            let e = &ev.edges.edgels[i as usize];
            if ev.tangent(i).dot(dir).abs() < cos_along {
                continue;
            }
            let d = (Vector2::new(e.x as f64, e.y as f64) - u.coords).dot(&normal);
            if d.abs() <= search && best.is_none_or(|b| d.abs() < b.abs()) {
                best = Some(d);
            }
        }
    }
    best
}

/// The image rows: each camera-facing model edge's samples pulled onto their edgels, in the
/// image of `ev`'s camera, which sits at `cam_from_left` from the `cam` (left camera) frame the
/// pose is in.
fn image_rows(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    ev: &ImageEvidence,
    cam_from_left: &Isometry3<f64>,
    search: f64,
    keep: &dyn Fn(usize, &Point3<f64>) -> bool,
    rows: &mut Rows,
) {
    let cam = ev.cam;
    // The steps of the search reach this far (see [`nearest_edgel_across`]).
    let looks = looks_across((2.0 * search) as i64 as f64 * 0.5);
    let seen = cam_from_left * pose;
    let eye = super::model::eye_of(&seen);
    for (k, line) in model.lines.iter().enumerate() {
        if !model.faces_eye(k, &eye) {
            continue;
        }
        let (a, b) = (seen * line.a, seen * line.b);
        let (Some(pa), Some(pb)) = (cam.project_cam(&a), cam.project_cam(&b)) else { continue };
        let len = (pb - pa).norm();
        if len < 2.0 * SAMPLE_PX {
            continue;
        }
        let dir = (pb - pa) / len;
        let normal = Vector2::new(-dir.y, dir.x);
        let bins = ImageEvidence::bins_along(dir);
        let steps = (len / SAMPLE_PX) as usize;
        for step in 1..steps {
            let t = step as f64 / steps as f64;
            let x = a + (b - a) * t;
            let Some(u) = cam.project_cam(&x) else { continue };
            let Some(d) = nearest_edgel_across(ev, &u, (&dir, bins), (search, &looks)) else { continue };
            // Last, as it may be dear (the polish tests samples against solids).
            if !keep(k, &x) {
                continue;
            }
            let z = x.z;
            let jacobian =
                Matrix2x3::new(cam.fx / z, 0.0, -cam.fx * x.x / (z * z), 0.0, cam.fy / z, -cam.fy * x.y / (z * z));
            // The pose moves in the left camera's frame: the pull, turned back into it.
            let pull = cam_from_left.rotation.inverse() * (jacobian.transpose() * normal);
            let x_left = pose * (line.a + (line.b - line.a) * t);
            rows.add(motion_row(&x_left, &pull), d);
        }
    }
}

/// The 3D rows: each end of a supporting scene line pulled onto its model line, across it, in
/// pixel-sized units (`fx / z` pixels per metre) so that both kinds of rows weigh alike.
fn line_rows(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    scene: &[Seg],
    pairs: &[(usize, usize)],
    fx: f64,
    rows: &mut Rows,
) {
    for &(i, j) in pairs {
        let ml = model.lines[i].transformed(pose);
        let across = [ml.dir.cross(&Vector3::z()), ml.dir.cross(&Vector3::x())]
            .into_iter()
            .max_by(|u, v| u.norm().total_cmp(&v.norm()))
            .map(|u| u.normalize())
            .unwrap_or_else(Vector3::x);
        let frame = [across, ml.dir.cross(&across)];
        for s in [scene[j].a, scene[j].b] {
            let x = ml.a + ml.dir * (s - ml.a).dot(&ml.dir);
            let scale = fx / x.z.max(1e-3);
            for e in &frame {
                rows.add(motion_row(&x, e) * scale, e.dot(&(s - x)) * scale);
            }
        }
    }
}

/// The pose refined on the image's edgels within `search` pixels of the projected model and on
/// the (model line, scene line) correspondences `pairs`; `None` when the image offers too
/// little to fit to.
pub fn refine_in_image(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    scene: &[Seg],
    pairs: &[(usize, usize)],
    ev: &ImageEvidence,
    search: f64,
) -> Option<Isometry3<f64>> {
    let rows_at = |pose: &Isometry3<f64>| {
        let mut rows = Rows::new();
        image_rows(model, pose, ev, &Isometry3::identity(), search, &|_, _| true, &mut rows);
        if rows.count < 12 {
            return None;
        }
        line_rows(model, pose, scene, pairs, ev.cam.fx, &mut rows);
        Some(rows)
    };
    gauss_newton(pose, rows_at, LOOK_STOP)
}

/// Damped Gauss-Newton from `pose` on the rows `rows_at` gathers at each step (`None`: too few
/// to fit to), until a step turns less than `done.0` radians and moves the model's origin less
/// than `done.1` metres, or [`ITERATIONS`] steps.
fn gauss_newton(
    pose: &Isometry3<f64>,
    rows_at: impl Fn(&Isometry3<f64>) -> Option<Rows>,
    done: (f64, f64),
) -> Option<Isometry3<f64>> {
    let mut pose = *pose;
    for _ in 0..ITERATIONS {
        let rows = rows_at(&pose)?;
        // A little damping keeps directions the evidence leaves loose where they are.
        let damping = 1e-6 * rows.normal.trace().max(1e-12);
        let delta = (rows.normal + Matrix6::identity() * damping).cholesky()?.solve(&rows.rhs);
        let (omega, tau) = (Vector3::new(delta[0], delta[1], delta[2]), Vector3::new(delta[3], delta[4], delta[5]));
        let next = Isometry3::from_parts(Translation3::from(tau), UnitQuaternion::from_scaled_axis(omega)) * pose;
        // The step turns about the camera's centre, and its shift `tau` mostly makes up for
        // the turn there (a part 0.8 m away, turned 1e-4 rad, has `tau` near 8e-5 m though it
        // moved by nothing): how far the part moved is how far its origin did.
        let moved = (next.translation.vector - pose.translation.vector).norm();
        pose = next;
        if omega.norm() < done.0 && moved < done.1 {
            break;
        }
    }
    Some(pose)
}

/// An image the stereo fit pulls the model onto: its evidence, and where its camera is from the
/// left camera's (`cam`) frame.
pub struct View<'a> {
    pub ev: &'a ImageEvidence<'a>,
    pub cam_from_left: Isometry3<f64>,
}

/// The pose refined on the edgels of several images at once (the stereo pair): each model edge
/// pulled onto its edgels in both, so that their disparity, to a fraction of a pixel along the
/// whole wireframe, fixes the depth and tilt that one image and the 3D lines fix poorly. Only
/// the samples `keep(view, line, x)` lets through are fitted (`x` in that view's camera
/// frame: what may be seen of the model there). Steps stop once smaller than `stop` (radians,
/// metres; [`FINE_STOP`] for the calibration flag). `None` when the images offer too little to
/// fit to.
pub fn refine_in_views(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    views: &[View],
    (search, stop): (f64, (f64, f64)),
    keep: &(dyn Fn(usize, usize, &Point3<f64>) -> bool + Sync),
) -> Option<Isometry3<f64>> {
    refine_in_views_above(model, pose, views, (search, stop), keep, None)
}

/// A floor no corner of the model may go under: a table (its frame the left camera's) and a
/// height above its top (metres; negative under it), where the parts rest.
pub(crate) type Floor<'t> = (&'t super::model::Table, f64);

/// A corner under the [`Floor`] is pulled up onto it this much harder than a sample onto its
/// edgel, per pixel it lies under: the floor is where the parts rest, not a guess.
const FLOOR_WEIGHT: f64 = 3.0;

/// [`refine_in_views`] with each corner of the model that lies under `floor` pulled up onto it.
pub(crate) fn refine_in_views_above(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    views: &[View],
    (search, stop): (f64, (f64, f64)),
    keep: &(dyn Fn(usize, usize, &Point3<f64>) -> bool + Sync),
    floor: Option<Floor>,
) -> Option<Isometry3<f64>> {
    refine_in_views_held(model, pose, views, (search, stop), keep, (floor, None))
}

/// The 3D lines a stereo fit is held to: the scene's lines, and the (model line, scene line)
/// pairs of the report's support.
pub(crate) type Anchor<'s> = (&'s [Seg], &'s [(usize, usize)]);

/// Each 3D line of an [`Anchor`] pulls onto its model line this much harder than a sample onto
/// its edgel, per pixel it lies off: a stereo line is a whole edge matched in both images, a
/// sample a few pixels of one. Chosen on tuning seeds (docs/TUNING.md, "The stereo polish held
/// to its 3D lines"): over its nine sets, 2, 3, 5 and 10 gave 58, 54, 56 and 57 false reports
/// where 1 gave 62 and the polish on the images alone 68.
const ANCHOR_WEIGHT: f64 = 3.0;

/// [`refine_in_views_above`] with each scene line of `anchor` pulled onto its model line too
/// (in pixel-sized units, times [`ANCHOR_WEIGHT`]).
pub(crate) fn refine_in_views_held(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    views: &[View],
    (search, stop): (f64, (f64, f64)),
    keep: &(dyn Fn(usize, usize, &Point3<f64>) -> bool + Sync),
    (floor, anchor): (Option<Floor>, Option<Anchor>),
) -> Option<Isometry3<f64>> {
    use rayon::prelude::*;
    let rows_at = |pose: &Isometry3<f64>| {
        // The views' rows gathered in parallel, then added in the views' order.
        let per_view: Vec<Rows> = views
            .par_iter()
            .enumerate()
            .map(|(i, v)| {
                let mut rows = Rows::new();
                image_rows(model, pose, v.ev, &v.cam_from_left, search, &|k, x| keep(i, k, x), &mut rows);
                rows
            })
            .collect();
        let mut rows = per_view.into_iter().fold(Rows::new(), |all, v| Rows {
            normal: all.normal + v.normal,
            rhs: all.rhs + v.rhs,
            count: all.count + v.count,
        });
        let enough = rows.count >= 12 * views.len();
        if let (Some((table, level)), Some(v)) = (floor, views.first()) {
            floor_rows(model, pose, (table, level), v.ev.cam.fx, &mut rows);
        }
        if let (Some((scene, pairs)), Some(v)) = (anchor, views.first()) {
            line_rows(model, pose, scene, pairs, ANCHOR_WEIGHT * v.ev.cam.fx, &mut rows);
        }
        enough.then_some(rows)
    };
    gauss_newton(pose, rows_at, stop)
}

/// Each corner of `model` at `pose` lying under the floor pulled up onto it, along the table's
/// up, in pixel-sized units (`fx / z` pixels per metre) times [`FLOOR_WEIGHT`].
fn floor_rows(model: &MatcherModel, pose: &Isometry3<f64>, (table, level): Floor, fx: f64, rows: &mut Rows) {
    let up = Vector3::from(table.up);
    for c in &model.corners {
        let x = pose * c;
        let under = level - table.height_of(&x);
        if under > 0.0 {
            let scale = FLOOR_WEIGHT * fx / x.z.max(1e-3);
            rows.add(motion_row(&x, &up) * scale, under * scale);
        }
    }
}

/// Steps of the stereo fit small enough to stop at (radians, metres): the calibration flag's,
/// whose sightings the hand-eye solve averages to a fraction of a millimetre.
pub const FINE_STOP: (f64, f64) = (1e-6, 1e-7);

#[cfg(test)]
mod tests {
    use super::*;

    /// A wedge whose images both show it 3 mm down into the table, every sample pulling it
    /// down: fitted alone it sinks with them; held above the floor, its lowest corner stays
    /// within a millimetre of the top (a soft hold, [`FLOOR_WEIGHT`], against a hundred-odd
    /// samples; where a reading sinks, few edges pull it there).
    #[test]
    fn corners_are_held_above_the_floor() {
        use crate::matcher::fixtures::{model, verged_pair};
        use crate::matcher::verify::{RightImage, drawn::model_edges};
        let wedge = model("wedge");
        let (left, right) = verged_pair();
        let table = super::super::model::Table::from_cam_from_table(&left.cam_from_world());
        let on_top = left.cam_from_world()
            * Isometry3::from_parts(
                Translation3::new(0.01, 0.02, 0.0),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7),
            );
        let lowest = |pose: &Isometry3<f64>| super::super::table::lowest_height(&table, &wedge, pose);
        let up = Vector3::from(table.up);
        let resting = Translation3::from(-up * lowest(&on_top)) * on_top;
        let sunk = Translation3::from(-up * 0.003) * resting;
        let right_from_cam = right.cam_from_world() * left.world_from_cam;
        let (left_edges, _) = model_edges(&wedge, &sunk, &left);
        let (right_edges, _) = model_edges(&wedge, &(right_from_cam * sunk), &right);
        let ev = ImageEvidence::new(&left, &left_edges, Vec::new())
            .with_right(RightImage { ev: ImageEvidence::new(&right, &right_edges, Vec::new()), right_from_cam });
        let right_ev = &ev.right.as_ref().unwrap().ev;
        let views = [
            View { ev: &ev, cam_from_left: Isometry3::identity() },
            View { ev: right_ev, cam_from_left: right_from_cam },
        ];
        let fit =
            |floor| refine_in_views_above(&wedge, &resting, &views, (3.0, FINE_STOP), &|_, _, _| true, floor).unwrap();
        let alone = lowest(&fit(None));
        assert!((alone + 0.003).abs() < 2e-4, "fitted alone, the lowest corner at {:.2} mm", alone * 1e3);
        let held = lowest(&fit(Some((&table, 0.0))));
        assert!(held > -1e-3, "held, the lowest corner at {:.2} mm", held * 1e3);
    }

    /// From 3 degrees and 3 mm off, the image and one true 3D line bring a widget back to
    /// within a fraction of a millimetre and degree of where its edgels are.
    #[test]
    fn a_pose_a_few_degrees_off_is_pulled_onto_its_edgels() {
        let model = crate::matcher::fixtures::model("widget");
        let cam = crate::matcher::fixtures::camera_at(Point3::new(0.0, -0.5, 0.6));
        let truth = cam.cam_from_world()
            * Isometry3::from_parts(
                Translation3::new(0.01, 0.02, 0.02),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7),
            );
        let (edges, _) = crate::matcher::verify::drawn::model_edges(&model, &truth, &cam);
        let ev = ImageEvidence::new(&cam, &edges, Vec::new());
        // One 3D line: the longest camera-facing edge, as stereo would give it.
        let k = (0..model.lines.len())
            .filter(|&k| model.faces_camera(k, &truth))
            .max_by(|&a, &b| model.lines[a].len.total_cmp(&model.lines[b].len))
            .unwrap();
        let scene = vec![model.lines[k].transformed(&truth)];
        // Turned about the object's own origin, and shifted.
        let turn = Isometry3::rotation(Vector3::new(0.03, -0.02, 0.035));
        let start = Translation3::new(0.002, -0.002, 0.001) * truth * turn;
        let got = refine_in_image(&model, &start, &scene, &[(k, 0)], &ev, SEARCH_PX).unwrap();
        let (pos, rot) =
            ((got.translation.vector - truth.translation.vector).norm(), got.rotation.angle_to(&truth.rotation));
        assert!(pos < 0.5e-3 && rot < 0.3f64.to_radians(), "{:.2} mm, {:.2} deg off", pos * 1e3, rot.to_degrees());
        let before = start.rotation.angle_to(&truth.rotation);
        assert!(before > 2.5f64.to_radians(), "the test starts {:.1} deg off", before.to_degrees());
    }

    /// The calibration flag 0.7 m from a verged pair: from 0.9 deg and 1 mm off, its checker's
    /// edgels in both images bring it back onto itself, and so do those of the right image alone
    /// (whose rows go through the pair's geometry), each within a hundredth of a millimetre and
    /// degree. (Fitting the outline too ends 0.17 deg off even on these exact edgels: the
    /// plate's front rim and the back rim's silhouette lie a pixel or two apart, and samples
    /// of one find the other's edgels.)
    #[test]
    fn a_flag_a_degree_off_is_pulled_onto_its_edgels_in_both_images() {
        let model = crate::matcher::fixtures::model("flag");
        let (left, right) = crate::matcher::fixtures::verged_pair();
        let world_from_flag = Isometry3::from_parts(
            Translation3::new(0.01, 0.02, 0.05),
            UnitQuaternion::from_euler_angles(1.1, 0.2, 0.4),
        );
        let left_from_flag = left.cam_from_world() * world_from_flag;
        let right_from_left = right.cam_from_world() * left.world_from_cam;
        let (left_edges, _) = crate::matcher::verify::drawn::model_edges(&model, &left_from_flag, &left);
        let (right_edges, _) =
            crate::matcher::verify::drawn::model_edges(&model, &(right_from_left * left_from_flag), &right);
        let (lev, rev) =
            (ImageEvidence::new(&left, &left_edges, Vec::new()), ImageEvidence::new(&right, &right_edges, Vec::new()));
        let views = [
            View { ev: &lev, cam_from_left: Isometry3::identity() },
            View { ev: &rev, cam_from_left: right_from_left },
        ];
        let start = Translation3::new(0.0007, -0.0005, 0.0005)
            * left_from_flag
            * Isometry3::rotation(Vector3::new(0.012, -0.01, 0.004));
        for (name, vs) in [("both images", &views[..]), ("the right image", &views[1..])] {
            let got = refine_in_views(&model, &start, vs, (3.0, FINE_STOP), &|_, k, _| model.is_marking(k)).unwrap();
            let e = left_from_flag.inverse() * got;
            let (mm, deg) = (e.translation.vector.norm() * 1e3, e.rotation.angle().to_degrees());
            assert!(mm < 0.01 && deg < 0.01, "{name}: {mm:.4} mm, {deg:.4} deg off");
        }
    }
}
