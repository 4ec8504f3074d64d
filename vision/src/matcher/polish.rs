//! The stereo polish: each report's pose, once every look is done, pulled onto the edgels of
//! both images at once ([`super::image_fit::refine_in_views`]).
//!
//! The looks fit poses to the 3D lines and the left image, and a 3D line is only as good as
//! the matches stereo made along it. At a silhouette the two cameras can see different edges:
//! a narrow face that one camera sees and the other does not puts the outline on the face's
//! far edge in one image and on its near edge in the other, and the 3D line from matching the
//! two leans (on `widgets.toml` seed 484 a wedge's side, 2-3 px wide in the left image,
//! gave matches 0.5-1.6 px of disparity off along its length, and the wedge came out 6 deg
//! off). Fitting the wireframe to each image on its own, with the edges each camera faces,
//! matches nothing across the images: each camera's outline is the model's own there.
//! Samples that other reports' solids or the model's own bulk hide from a camera are left
//! out, so that a hidden edge is not pulled onto whatever lies in front of it. Where both
//! images do not show that pose more sharply than the report, the report is polished again
//! held to the 3D lines it rests on ([`polished_or_held`]): a leaning part fitted to the left
//! image a few degrees off is then pulled by the right image and its lines together, not slid
//! off onto other edges.
//!
//! Then the turns ([`turn_in_stereo`]): a report replaced by a turn of itself that both images
//! show more sharply. Where a turn fits as well, the report stands and is in doubt
//! ([`doubt`]).

use super::image_fit::{View, refine_in_views_held};
use super::model::{Located, MatchParams, MatcherModel, Seg};
use super::occlusion::Solid;
use super::support::support_at;
use super::verify::{ImageEvidence, image_support_unhidden};
use nalgebra::{Isometry3, Point3};

/// The passes' search widths across each model edge, pixels: wide first, from where the looks
/// may leave a pose a few degrees off, then narrower, so that edgels beside the right ones
/// (a face's other edge a pixel or two away) stop pulling.
pub const PASSES_PX: [f64; 3] = [3.0, 1.5, 1.0];

/// Steps of the last pass small enough to stop at (radians, metres): a hundredth of a millimetre,
/// against pose errors near 0.1 mm. The calibration flag's limits ([`super::image_fit::FINE_STOP`],
/// a hundred times finer) took a pass 4.6 steps on average on the bench scene.
const STOP: (f64, f64) = (1e-4, 1e-5);

/// Steps small enough to stop the passes before the last at: a tenth of a millimetre, well
/// inside the next pass's search (1.5 px is about a millimetre at the parts' distance), which
/// is all they are for. On the tuning seeds (`marvin eval locate`, `widgets.toml` 1-120,
/// `dense.toml` and `side_light.toml` 1-60) the same reports as with [`STOP`] for every pass,
/// pose medians within a thousandth of a millimetre; the matcher's instructions on the bench
/// scene 867 M -> 840 M. (A millimetre, a hundred times [`STOP`], saved 60 M but moved the
/// dense world's median 0.103 -> 0.106 mm.)
const COARSE_STOP: (f64, f64) = (1e-3, 1e-4);

/// A polished pose is kept only if the 3D lines find at least this share of the support they
/// found at the report's pose: the polish corrects a few degrees, and the lines fix where the
/// part is to a few millimetres. (First seen on a reporting seed, `widgets.toml` 10002, where in
/// `marvin run`'s seventh cycle a wedge's outline in the right image slid onto other edges and
/// took it 17 mm towards the cameras, off the table.) On tuning seeds (`eval locate --scenes 50
/// --seed 1` of `widgets.toml`, both presets, and `--scenes 30` of `dense.toml`) no check, 0.8
/// and 0.9 locate the same parts within one or two of hundreds, and no figure tells them apart
/// (docs/TUNING.md): 0.8 stands, as the guard against the case seen.
const KEEP_SUPPORT: f64 = 0.8;

/// Every report's pose polished on both images of the pair (unchanged without the right image,
/// where a pass finds too little to fit to, or where the polished pose loses the 3D lines'
/// support, [`KEEP_SUPPORT`], unless both images show it more sharply, [`sharper_in_both`]);
/// its grasps move with it.
pub fn polish_in_stereo(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    kept: &mut [Located],
) {
    polish_those(models, (scene, p), ev, kept, &vec![true; kept.len()]);
}

/// [`polish_in_stereo`] for the reports of `kept` marked in `which` only, the others standing
/// where they are as solids that may hide them.
pub(crate) fn polish_those(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    kept: &mut [Located],
    which: &[bool],
) {
    polish_marked(models, (scene, p), ev, kept, (which, None));
}

/// The reports of `kept` sunk into the table ([`SUNK_M`] under the scene's
/// [`super::table::resting_level`]) polished again with their corners held on it, once the
/// turns have had their say (a turn that rests is the better answer to a sunk reading, and it
/// is judged on the reading as the looks left it).
///
/// Why: where a part leans or lies partly hidden, the few edges in view leave its tilt a few
/// degrees free, and a reading tilted so sinks a corner into the table. On the tuning seeds
/// (`marvin eval locate` through tuning seed 1's calibrations: realistic `widgets.toml` 1-1100,
/// `dense.toml` 1-200; ideal `widgets.toml` 1-400, `dense.toml` 1-160) four near misses came
/// right (realistic `widgets.toml` 547, 740, 893, 991: 5.3-7.1 deg off before; 271 with
/// [`LIFT_SLACK`]) and nothing else changed. Held so in the first polish, before the turns,
/// it lifted two wedges read with bottom and slope swapped out of the table, where the turn
/// that rests no longer took them (seed 627).
pub(crate) fn lift_sunk(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    kept: &mut [Located],
) {
    let Some(table) = p.table.as_ref() else { return };
    let Some(level) = super::table::resting_level(models, kept, table) else { return };
    let sunk: Vec<bool> = kept
        .iter()
        .map(|r| models.iter().find(|m| m.name == r.model).is_some_and(|m| sinks((table, level), m, &r.cam_from_model)))
        .collect();
    polish_marked(models, (scene, p), ev, kept, (&sunk, Some((table, level))));
}

/// A sunk report held on the table ([`lift_sunk`]) is kept, besides where the polish keeps a
/// pose, where each image shows as much of its wireframe in view along edgels as at the sunk
/// pose, less this: the 3D lines it would keep are the ones that held it in the table. A block
/// leaning on a channel (realistic `widgets.toml` tuning seed 271) came out of the table 5.3 ->
/// 4.1 deg off on 0.03 of its wireframe along 3D lines where it lay on 0.16 (one line of the
/// channel's under it). On the tuning sets (as for [`lift_sunk`]) it changed no other report.
const LIFT_SLACK: f64 = 0.05;

/// [`polish_those`], each report's corners held above `floor` if one is given.
fn polish_marked(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    kept: &mut [Located],
    (which, floor): (&[bool], Option<super::image_fit::Floor>),
) {
    use rayon::prelude::*;
    let Some((views, solids)) = stereo_views(models, ev, kept).filter(|_| which.contains(&true)) else { return };
    let model_of = |r: &Located| models.iter().find(|m| m.name == r.model);
    let poses: Vec<Option<Isometry3<f64>>> = kept
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            if !which.get(i).copied().unwrap_or(false) {
                return None;
            }
            let others = others_than(&solids, i);
            let model = model_of(r)?;
            let pose = polished_or_held(model, &r.cam_from_model, (scene, p), &others, &views, floor);
            let support = |pose: &Isometry3<f64>| support_at(model, pose, scene, p).0;
            let lines_kept = support(&pose) >= KEEP_SUPPORT * support(&r.cam_from_model);
            let shown_as_well = || {
                let (before, after) = (
                    shares_in_view(model, &r.cam_from_model, &views, &others),
                    shares_in_view(model, &pose, &views, &others),
                );
                before.iter().zip(&after).all(|(b, a)| *a >= b - LIFT_SLACK)
            };
            (lines_kept
                || sharper_in_both(model, (&r.cam_from_model, &pose), &views, &others)
                || (floor.is_some() && shown_as_well()))
            .then_some(pose)
        })
        .collect();
    for (r, pose) in kept.iter_mut().zip(poses) {
        let (Some(pose), Some(model)) = (pose, model_of(r)) else { continue };
        r.cam_from_model = pose;
        r.grasps = model.grasps_at(&pose);
    }
}

/// Both images as views (none without the right image), and each report's solid in each
/// camera's frame, where the report stands (made once: every pass of every other report tests
/// its samples against them).
fn stereo_views<'e>(
    models: &[MatcherModel],
    ev: &'e ImageEvidence<'e>,
    kept: &[Located],
) -> Option<([View<'e>; 2], SolidsInViews)> {
    let right = ev.right.as_deref()?;
    let views = [
        View { ev, cam_from_left: Isometry3::identity() },
        View { ev: &right.ev, cam_from_left: right.right_from_cam },
    ];
    let model_of = |r: &Located| models.iter().find(|m| m.name == r.model);
    let solids = views
        .iter()
        .map(|v| kept.iter().map(|r| Some(Solid::new(model_of(r)?, &(v.cam_from_left * r.cam_from_model)))).collect())
        .collect();
    Some((views, solids))
}

/// Per view, each report's solid in that camera's frame (`None` for a model not known).
type SolidsInViews = Vec<Vec<Option<Solid>>>;

/// In each view, the solids of every report but report `i`.
fn others_than(solids: &[Vec<Option<Solid>>], i: usize) -> Vec<Vec<&Solid>> {
    solids
        .iter()
        .map(|in_view| in_view.iter().enumerate().filter(|(k, _)| *k != i).filter_map(|(_, s)| s.as_ref()).collect())
        .collect()
}

/// Whether `model` polished (`poses.1`) runs along edgels for as much of its wireframe as the
/// report (`poses.0`) does in each image or more, and for more in the two together (its share
/// of the wireframe that `others`, in each view's camera frame, leave in view).
///
/// Why: where a few 3D lines lean (stereo's matches along an edge at a silhouette, or along a
/// line that runs near the rasters' direction), the looks fit the part to them a few degrees
/// off, and the 3D lines hold the polished pose back: over tuning seeds 501-1500 of
/// `widgets.toml` five reports 5.1-5.9 deg off were polished onto the truth (within 0.3 deg and
/// 0.4 mm of it) and refused, having kept 0.50-0.79 of their 3D support, while the share of
/// their wireframe along edgels rose in both images (0.58 -> 0.94 and 0.68 -> 0.95 in one).
/// A pose that slides onto other edges in one image loses edgels in the other. On the tuning
/// seeds (`marvin eval locate`, `widgets.toml` 1-1500, `dense.toml` and `side_light.toml`
/// 1-200) this put 5 near-misses right and located 3 more parts of the dense world; it took
/// one T-piece 22% in view (too little to count as a miss) from 3.5 to 5.4 deg off (seed 160).
fn sharper_in_both(
    model: &MatcherModel,
    (report, polished): (&Isometry3<f64>, &Isometry3<f64>),
    views: &[View],
    others: &[Vec<&Solid>],
) -> bool {
    let (before, after) =
        (shares_in_view(model, report, views, others), shares_in_view(model, polished, views, others));
    before.iter().zip(&after).all(|(b, a)| a >= b) && after.iter().sum::<f64>() > before.iter().sum::<f64>()
}

/// The share of `model`'s wireframe at `pose` in view that runs along edgels, in each view,
/// with `others` (in each view's camera frame) hiding what lies behind them.
fn shares_in_view(model: &MatcherModel, pose: &Isometry3<f64>, views: &[View], others: &[Vec<&Solid>]) -> Vec<f64> {
    views.iter().zip(others).map(|(v, o)| image_support_unhidden(model, &(v.cam_from_left * pose), v.ev, o).0).collect()
}

/// `pose` polished on both images alone ([`polished`]) where both show the model more sharply
/// there ([`sharper_in_both`]); else polished held to the 3D lines along it at `pose`.
///
/// Why: a part that leans or lies partly hidden shows its tilt poorly in the left image, and
/// the looks fit it there; where the right image disagrees, the polish on both images alone
/// slid off onto other edges (and was refused, [`KEEP_SUPPORT`]), leaving the report as the
/// looks left it. On realistic `widgets.toml` tuning seeds 7511-7710 the four reports 5.4-6.8
/// deg off that were traced ran along edgels in the left image for more of their wireframe than
/// the truth did (0.80-0.96 against 0.63-0.80), in the right image for less (0.55-0.79 against
/// 0.66-0.86), and along 3D lines mostly for less: a wedge's polish alone moved 8.8 mm and
/// kept none of its lines, while from the truth it stayed within 0.9 mm and 0.2 deg. Held to
/// its lines, it came within 5 deg. Where both images show the polish alone more sharply, the
/// lines may be the ones that lean (a line along a silhouette), and it stands as before.
pub(crate) fn polished_or_held(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    (scene, p): (&[Seg], &MatchParams),
    others: &[Vec<&Solid>],
    views: &[View],
    floor: Option<super::image_fit::Floor>,
) -> Isometry3<f64> {
    let alone = polished(model, pose, others, views, floor);
    if sharper_in_both(model, (pose, &alone), views, others) {
        return alone;
    }
    let (_, pairs) = super::support::support(model, pose, scene, &vec![true; scene.len()], p);
    let pairs: Vec<(usize, usize)> = pairs.iter().map(|&(i, j, _)| (i, j)).collect();
    polished_along(model, pose, others, views, (floor, Some((scene, &pairs))))
}

/// `pose` after the passes of [`PASSES_PX`], each fitting only what neither `others` (the
/// other reports' solids, in each view's camera frame) nor the model's own bulk at the pass's
/// start hides from each camera.
pub(crate) fn polished(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    others: &[Vec<&Solid>],
    views: &[View],
    floor: Option<super::image_fit::Floor>,
) -> Isometry3<f64> {
    polished_along(model, pose, others, views, (floor, None))
}

/// [`polished`], each pass held to the 3D lines of `anchor` if one is given.
fn polished_along(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    others: &[Vec<&Solid>],
    views: &[View],
    (floor, anchor): (Option<super::image_fit::Floor>, Option<super::image_fit::Anchor>),
) -> Isometry3<f64> {
    PASSES_PX.iter().enumerate().fold(*pose, |pose, (pass, &search)| {
        let stop = if pass + 1 < PASSES_PX.len() { COARSE_STOP } else { STOP };
        let hiders: Vec<(Solid, Vec<&Solid>)> =
            views.iter().zip(others).map(|(v, others)| hiders_in_view(model, &pose, others, v)).collect();
        let keep = |view: usize, _: usize, x: &Point3<f64>| {
            let (own, others) = &hiders[view];
            !own.hides(x) && !others.iter().any(|s| s.hides(x))
        };
        refine_in_views_held(model, &pose, views, (search, stop), &keep, (floor, anchor)).unwrap_or(pose)
    })
}

/// The solids that may hide part of `model` at `pose` from view `v`'s camera, in its frame:
/// the model's own, and those of `others` whose cones of sight overlap it. The own solid stays
/// where the pass started while the pose moves, so a sample carried behind where the part's
/// surface was is dropped too: leaving out a convex part's own solid (it hides none of its
/// facing edges where it stands) let two wedges on the tuning seeds slide to 5.1 and 5.8 deg
/// off (`widgets.toml` seeds 21, 154; `eval locate` 1-500: 10 false reports against 8).
fn hiders_in_view<'a>(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    others: &[&'a Solid],
    v: &View,
) -> (Solid, Vec<&'a Solid>) {
    let own = Solid::new(model, &(v.cam_from_left * pose));
    let others = others.iter().copied().filter(|s| s.may_hide(&own)).collect();
    (own, others)
}

/// Each report replaced by the best of its turns ([`super::turns::in_stereo`]), refitted on the 3D
/// lines and the left image and polished on both, that keeps [`TURN_KEEP_SUPPORT`] of its 3D
/// support and, against the report, runs along edgels for as much of its wireframe in view as
/// the report does in each image or more and for more in the two together, and for as much of
/// its whole wireframe in the left image. Only turns that start near the report along edgels
/// in both images ([`TURN_START_SLACK`]) are refitted. A turn clearly sharper in both images
/// ([`CLEAR_GAIN`]) needs less of the 3D support and the whole wireframe; one far sharper
/// ([`FAR_GAIN`]) less of the 3D support still. Returns which
/// reports were turned.
///
/// Why: a part read turned over (a wedge resting on its slope where it rests on its bottom, an
/// L-bracket face down) shares most of its lines with the part, and the left image alone, with
/// which the turns by depth and image judge it ([`super::turnover`]), often shows the two
/// alike; the right image, which sees the ends and sides from 13 deg away, tells them apart
/// where the wireframe runs through both. A turn must also not win by hiding more of itself
/// behind the other reports: the share along edgels counts only the wireframe in view. On the
/// tuning seeds (`marvin eval locate`, `widgets.toml` 1-1500, `dense.toml` and
/// `side_light.toml` 1-200) this put right 5 reports turned over (a wedge, two L-brackets, a
/// widget, a T-piece) and turned none that was right; without the whole-wireframe condition
/// it put right 8 and turned 3 right ones over (an L-bracket, a U-channel, a widget, each with
/// less of its whole wireframe along the left image's edgels than the report had).
pub(crate) fn turn_in_stereo(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    turns: &super::shading::TurnedCandidates,
    kept: &mut [Located],
) -> Vec<bool> {
    use rayon::prelude::*;
    let Some((views, solids)) = stereo_views(models, ev, kept) else { return vec![false; kept.len()] };
    let model_of = |r: &Located| models.iter().find(|m| m.name == r.model);
    let level = p.table.as_ref().and_then(|t| super::table::resting_level(models, kept, t).map(|level| (t, level)));
    let turned: Vec<Option<Isometry3<f64>>> = kept
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            let model = model_of(r)?;
            let others = others_than(&solids, i);
            let rests = |pose: &Isometry3<f64>| {
                level.is_some_and(|(t, level)| {
                    super::table::lowest_height(t, model, pose) >= level - RESTS_M
                        && !super::table::floats_flat((t, level), model, pose)
                })
            };
            let off_the_table =
                |l| sinks(l, model, &r.cam_from_model) || super::table::floats_flat(l, model, &r.cam_from_model);
            let sunk = level.is_some_and(off_the_table);
            // A turn may not sink into the table where the report does not: no part lies in
            // it. (Realistic `dense.toml` tuning seed 5393: a wedge on its bottom, read right,
            // was turned onto its slope 5.5 mm deep, by the image where they differ.)
            let sinks_at = |pose: &Isometry3<f64>| !sunk && level.is_some_and(|l| sinks(l, model, pose));
            best_turn(
                model,
                (scene, p),
                (&views, &others),
                turns,
                (&r.cam_from_model, sunk.then_some(&rests)),
                &sinks_at,
            )
        })
        .collect();
    kept.iter_mut()
        .zip(turned)
        .map(|(r, pose)| {
            let (Some(pose), Some(model)) = (pose, models.iter().find(|m| m.name == r.model)) else { return false };
            let (support, pairs) = super::support::support(model, &pose, scene, &vec![true; scene.len()], p);
            *r = Located {
                model: r.model.clone(),
                cam_from_model: pose,
                support,
                support_fraction: support / model.total_length,
                scene_lines: super::support::scene_lines_of(&pairs),
                image_support: super::verify::image_support(model, &pose, ev),
                grasps: model.grasps_at(&pose),
            };
            true
        })
        .collect()
}

/// A report whose lowest corner lies this far (metres) under the scene's
/// [`super::table::resting_level`] is sunk ([`sinks`]): no part lies in the table. Such a report may be replaced by a turn that rests (its
/// lowest corner no more than [`RESTS_M`] under the level) where the two tie, the turn keeping
/// [`TURN_KEEP_SUPPORT`] of the report's 3D support and [`SUNK_TIE_SLACK`] of its share along
/// edgels in view; every turn of a sunk report is refitted, wherever it starts.
///
/// Why: a wedge read with its bottom and slope swapped fills nearly the space the wedge
/// does, and where the end that tells them apart is hidden the images tie (realistic
/// `widgets.toml` tuning seeds 317 and 627: in view 1.804 read against 1.806 turned, and 1.634
/// against 1.592), but the reading sinks 1.7-2.1 mm into the table and the turn, the truth,
/// rests on it (0.4-0.6 mm).
const SUNK_M: f64 = 0.0015;
/// See [`SUNK_M`], metres.
const RESTS_M: f64 = 0.0008;
/// See [`SUNK_M`]: the share along edgels in view, summed over both images, that a resting
/// turn may fall short of a sunk report's.
const SUNK_TIE_SLACK: f64 = 0.05;

/// Whether `model` at `pose` lies sunk ([`SUNK_M`]) under `level`, a height above `table`'s top.
fn sinks((table, level): (&super::model::Table, f64), model: &MatcherModel, pose: &Isometry3<f64>) -> bool {
    super::table::lowest_height(table, model, pose) < level - SUNK_M
}

/// A test of a pose against the table: whether it rests on it, or sinks into it (see [`SUNK_M`]).
type TableTest<'a> = &'a (dyn Fn(&Isometry3<f64>) -> bool + Sync);

/// The best of the turns of `model` at `report` that [`turn_in_stereo`] takes, polished, with
/// `others` (in each view's camera frame) hiding what lies behind them; where the report is
/// sunk, with whether a pose rests ([`SUNK_M`]); turns for which `sinks_at` holds are not taken.
fn best_turn(
    model: &MatcherModel,
    (scene, p): (&[Seg], &MatchParams),
    (views, others): (&[View], &[Vec<&Solid>]),
    turns: &super::shading::TurnedCandidates,
    (report, sunk): (&Isometry3<f64>, Option<TableTest>),
    sinks_at: TableTest,
) -> Option<Isometry3<f64>> {
    use super::verify::{image_support, image_support_at_least};
    use rayon::prelude::*;
    let ev = views[0].ev;
    let in_view = |pose: &Isometry3<f64>| shares_in_view(model, pose, views, others);
    let support = |pose: &Isometry3<f64>| support_at(model, pose, scene, p).0;
    let (now, now_support, now_whole) = (in_view(report), support(report), image_support(model, report, ev));
    let now_sum: f64 = now.iter().sum();
    super::turns::in_stereo(model)
        .par_iter()
        .filter(|turn| !super::turns::is_symmetry(model, turn))
        .map(|turn| report * turn)
        // Refitting is most of the cost: only turns that start near the report are refitted.
        .filter(|start| {
            if sunk.is_some() {
                return true;
            }
            let keeps_the_lines = || support(start) >= APART_START_SUPPORT * now_support;
            let Some(whole) = image_support_at_least(model, start, ev, now_whole - APART_START_SLACK) else {
                return keeps_the_lines();
            };
            let then = in_view(start);
            let near =
                whole >= now_whole - TURN_START_SLACK && then.iter().zip(&now).all(|(t, n)| *t >= n - TURN_START_SLACK);
            near || then.iter().sum::<f64>() >= now_sum - APART_START_SUM_SLACK || keeps_the_lines()
        })
        .filter_map(|start| turns.refit(model, (scene, p), ev, start))
        .map(|c| polished(model, &c.pose, others, views, None))
        .filter(|pose| !sinks_at(pose))
        .map(|pose| (in_view(&pose), pose))
        .filter(|(then, pose)| {
            let (then_sum, then_support) = (then.iter().sum::<f64>(), support(pose));
            let sharper = then_support >= TURN_KEEP_SUPPORT * now_support
                && then.iter().zip(&now).all(|(t, n)| t >= n)
                && then_sum > now_sum
                && image_support(model, pose, ev) >= now_whole;
            let rests_where_the_report_sinks = || {
                sunk.is_some_and(|rests| rests(pose))
                    && then_support >= TURN_KEEP_SUPPORT * now_support
                    && then_sum >= now_sum - SUNK_TIE_SLACK
            };
            let clearly_sharper = || {
                (then_support >= CLEAR_KEEP_SUPPORT * now_support
                    && then.iter().zip(&now).all(|(t, n)| t - n >= CLEAR_GAIN)
                    && image_support(model, pose, ev) >= now_whole - CLEAR_WHOLE_SLACK)
                    || (then_support >= FAR_KEEP_SUPPORT * now_support
                        && then.iter().zip(&now).all(|(t, n)| t - n >= FAR_GAIN)
                        && image_support(model, pose, ev) >= now_whole)
            };
            sharper
                || clearly_sharper()
                || (then_support >= APART_KEEP_SUPPORT * now_support
                    && then_sum >= now_sum
                    && super::ties::shown_where_apart(model, (report, pose), (views, others)))
                || rests_where_the_report_sinks()
        })
        // In the turns' order, whichever thread finishes first: of turns that tie, the last.
        .collect::<Vec<_>>()
        .into_iter()
        .max_by(|a, b| a.0.iter().sum::<f64>().total_cmp(&b.0.iter().sum::<f64>()))
        .map(|(_, pose)| pose)
}

/// A turn the image shows where it differs from the report
/// ([`super::ties::shown_where_apart`]) replaces it if it keeps this share of its 3D support
/// (as the turn by image asks, `IMAGE_TURN_KEEP` in [`super::turnover`]: a wedge resting on
/// its slope, read on its bottom, matched 0.41 m and turned 0.45, `widgets.toml` tuning seed
/// 153) and runs along edgels for as much of its wireframe in view in the two images together.
///
/// Why: the whole wireframe's share along edgels weighs mostly the edges the two readings
/// share; where they differ (a wedge's ends, leaning 21 deg one way or the other) the image
/// tells them apart plainly. On the tuning seeds (`marvin eval locate`, realistic `widgets.toml`
/// 1-300 and `dense.toml` 1-60 through tuning seed 1's calibrations, ideal `widgets.toml` 1-100
/// and `dense.toml` 1-60), of the 6,400 turns of right reports refitted, none gained more than
/// 0.10 where apart in every image it could be measured in; the four false reports it turned
/// (three wedges on their slope read on their bottom, an L-bracket turned over) gained 0.32-0.83.
const APART_KEEP_SUPPORT: f64 = 0.9;
/// Such turns are refitted if, turned where the report lies, they run along edgels for no less
/// than the report's share of its whole wireframe less this in the left image (the four
/// started 0.00-0.10 below it)...
const APART_START_SLACK: f64 = 0.15;
/// ...and of their wireframe in view in the two images together, no less than the report's
/// less this (they started up to 0.18 below it). Twice the turns are refitted as before.
const APART_START_SUM_SLACK: f64 = 0.2;
/// ...or, whatever the images show of them where the report lies, if they keep this share of
/// its 3D support there. A wedge read end for end on its slope ([`super::turns::of`]) turned
/// back about the slope's normal keeps the slope's lines, but where it stands on its tall end
/// its turned outline starts well off both images' edgels (realistic `widgets.toml` tuning
/// seeds 230 and 331: 0.64 of the whole wireframe in the left image against 0.99 and 0.88 read,
/// 3D support 0.76 and 0.79 of the report's). Refitted, both came out right (0.5 deg, 0.9 mm).
/// On the tuning sets (as for [`APART_KEEP_SUPPORT`]) 0.5 and 0.7 gave the same reports, 0.85
/// missed seed 230; refitting every turn, the same reports as 0.7 for 60% more time in the
/// matcher, where 0.7 costs none that the medians show (12.8 -> 12.3 ms on `widgets.toml`
/// 301-700).
const APART_START_SUPPORT: f64 = 0.7;

/// A turn that runs along edgels for this share more of its wireframe in view than the report
/// does, in each image, replaces it though it keeps only [`CLEAR_KEEP_SUPPORT`] of its 3D
/// support and [`CLEAR_WHOLE_SLACK`] less of its whole wireframe in the left image: the 3D
/// lines a wrong reading lies along need not all be the part's (a wedge with bottom and slope
/// swapped, realistic `widgets.toml` tuning seed 913: 299 mm matched against the turn's 236,
/// in view 0.68 / 0.66 against 0.86 / 0.83). Right reports' turns gained 0.074 at most in both
/// images (docs/TUNING.md, session 66).
const CLEAR_GAIN: f64 = 0.08;
/// See [`CLEAR_GAIN`].
const CLEAR_KEEP_SUPPORT: f64 = 0.7;
/// See [`CLEAR_GAIN`].
const CLEAR_WHOLE_SLACK: f64 = 0.1;

/// A turn that runs along edgels for this share more of its wireframe in view than the report
/// does in each image, and for as much of its whole wireframe in the left image, replaces it
/// though it keeps only [`FAR_KEEP_SUPPORT`] of its 3D support: a report read on other parts'
/// 3D lines loses them when turned onto its own. An L-bracket read with its arm on the bar's
/// other side, along a neighbour's edge (realistic `dense.toml` tuning seed 6283), turned back
/// onto its bar's other side ([`super::turns::in_stereo`]) ran along edgels for 0.96 / 0.96 of
/// its wireframe in view against 0.51 / 0.44, and 0.71 of its whole wireframe against 0.50,
/// on 0.52 of the report's 3D support. `marvin eval locate` through tuning seed 1's
/// calibrations: it put that report right and changed no other on realistic `dense.toml`
/// 5001-5400 and 6001-6300, `widgets.toml` 4401-4700 and ideal `dense.toml` 5001-5200; 0.2
/// gave the same; 0.1 turned a right bracket wrong (5241).
const FAR_GAIN: f64 = 0.3;
/// See [`FAR_GAIN`].
const FAR_KEEP_SUPPORT: f64 = 0.5;

/// A turn replaces a report in [`turn_in_stereo`] only if it keeps this share of the report's
/// 3D support: all of it, bar rounding. Every turn taken on the tuning seeds that put a report
/// right kept its support or gained (x1.00-1.27: `marvin eval locate`, `widgets.toml` 1-1500,
/// `dense.toml` 1-400, `side_light.toml` 1-200, with edgels deblurred and not), while the two
/// that turned right reports over (with deblurred edgels, [`crate::CannyParams::deblur`]: a
/// wedge, `widgets.toml` seed 315, by 0.05 of its share along edgels in the two images; a
/// U-channel, 373) kept x0.97 and x0.90 of it, which the turns by depth and image's 0.9 let
/// through.
const TURN_KEEP_SUPPORT: f64 = 0.99;
/// A turn is refitted only if, turned where the report lies, it runs along edgels for no less
/// than the report's share less this, of its whole wireframe in the left image (as the turn by
/// image asks, [`super::turnover`]) and of what is in view in each image. (Asking it of the
/// right image too changed no report on the tuning seeds and saved refits and polishes.)
const TURN_START_SLACK: f64 = 0.1;

pub mod doubt;

#[cfg(test)]
mod tests;
