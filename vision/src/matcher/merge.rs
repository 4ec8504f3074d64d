//! All models at once: each model's matcher in parallel, then the merge that keeps the best
//! supported of reports that share lines or space, the second look (objects with too few 3D
//! lines), the third (candidates partly hidden by objects already located), the table look
//! and the image look (parts lying flat on too few 3D lines, or none), each report set
//! against other models read from its lines ([`rival_reading`]), the reports turned over where
//! the edgels' depths or the image say so ([`super::turnover::turn_by_depth`],
//! [`super::turnover::turn_by_image`]), their poses polished on both images and turned where
//! both show a turn more sharply ([`super::polish`]), the reports' faces read for one light
//! ([`super::shading::judge_by_shading`]), and last the image look again with that light: in
//! full where the check dropped a report, else on the starts the first image look gave up for
//! want of edgels, judged on the edges the light lets show ([`super::contrast`]). Of two reports
//! left sharing more than a sliver of space, the weaker is dropped ([`super::overlap`]).

use super::hypotheses::{ScenePairs, scene_pairs};
use super::model::{Located, MatchParams, MatcherModel, Seg};
use super::occlusion::{MIN_IN_VIEW, Solid};
use super::overlap::fill_the_same_space;
use super::search::{Search, locate_from};
use super::table::through_table;
use super::verify::{Explained, ImageEvidence, MAX_EXPLAINED, image_support_unhidden};
use nalgebra::Isometry3;

/// Every model sought in the scene, each by its own matcher (in parallel, as MARVIN gave each
/// model a virtual matcher of its own); where two reports explain mostly the same scene lines,
/// the better supported one stands.
pub fn locate_all(
    models: &[MatcherModel],
    scene: &[Seg],
    p: &MatchParams,
    image: Option<&ImageEvidence>,
) -> Vec<Located> {
    // Run on a thread of the pool: each parallel step entered from outside it waits for a
    // worker to wake, and the matcher takes a score of them.
    rayon::scope(|_| locate_all_in_pool(models, scene, p, image))
}

/// [`locate_all`], on a thread of rayon's pool.
fn locate_all_in_pool(
    models: &[MatcherModel],
    scene: &[Seg],
    p: &MatchParams,
    image: Option<&ImageEvidence>,
) -> Vec<Located> {
    use rayon::prelude::*;
    let pairs = scene_pairs(scene, p);
    let mut searches = first_looks(models, scene, &pairs, p, image);
    let mut kept = Vec::new();
    let mut claimed = vec![false; scene.len()];
    let all: Vec<Located> = searches.iter_mut().flat_map(|s| std::mem::take(&mut s.found)).collect();
    resolve(models, (scene, p), all, &mut kept, &mut claimed, image);
    if let Some(ev) = image.filter(|ev| !ev.lines.is_empty()) {
        let (solids, explained) = (solids_of(models, &kept), explained_by(models, &kept, ev));
        let second: Vec<Located> = models
            .par_iter()
            .flat_map(|m| super::second_look::locate(m, scene, &claimed, p, ev, (&solids, &explained)))
            .collect();
        resolve(models, (scene, p), second, &mut kept, &mut claimed, image);
    }
    if let Some(ev) = image {
        let third = hidden_in_part(models, &searches, (&kept, &claimed), p, ev);
        resolve(models, (scene, p), third, &mut kept, &mut claimed, image);
    }
    if let Some(ev) = image.filter(|_| p.table.is_some()) {
        let (solids, explained) = (solids_of(models, &kept), explained_by(models, &kept, ev));
        let on_table: Vec<Located> = models
            .par_iter()
            .zip(searches.par_iter())
            .flat_map_iter(|(m, s)| {
                super::table_look::locate(m, scene, &s.flat, &claimed, p, ev, (&solids, &explained))
            })
            .collect();
        resolve(models, (scene, p), on_table, &mut kept, &mut claimed, image);
    }
    let mut faint = Vec::new();
    if let Some(ev) = image {
        let from_image;
        (from_image, faint) = image_look(models, (scene, p), ev, &kept, &claimed, None);
        resolve(models, (scene, p), from_image, &mut kept, &mut claimed, image);
    }
    if let Some(ev) = image.filter(|ev| !ev.lines.is_empty()) {
        for i in 0..kept.len() {
            if let Some(rival) = rival_reading(models, scene, p, ev, &kept, i) {
                kept[i] = rival;
            }
        }
        super::superset::settle_larger(models, (scene, p), ev, super::superset::MAX_SUPPORT, &mut kept, 0);
        super::covering::settle_covered(models, (scene, p), ev, &mut kept, 0);
    }
    if let Some(ev) = image {
        let turns = super::shading::TurnedCandidates::default();
        super::turnover::turn_by_depth(models, (scene, p), ev, (RIVAL_MAX_SUPPORT, &turns), &mut kept);
        super::turnover::turn_by_image(models, (scene, p), ev, &turns, &mut kept);
        // Polished before the shading is judged: a face's grey level tells a reading a few
        // degrees off from one that fits, and the looks leave many a few degrees off. The
        // judge asks the pose before the polish too, and a reading it turns over is polished
        // after it.
        let mut unpolished: Vec<Isometry3<f64>> = kept.iter().map(|r| r.cam_from_model).collect();
        super::polish::polish_in_stereo(models, (scene, p), ev, &mut kept);
        // A report turned in stereo is judged on its turned reading alone.
        let in_stereo = super::polish::turn_in_stereo(models, (scene, p), ev, &turns, &mut kept);
        super::polish::lift_sunk(models, (scene, p), ev, &mut kept);
        for ((before, r), turned) in unpolished.iter_mut().zip(&kept).zip(in_stereo) {
            if turned {
                *before = r.cam_from_model;
            }
        }
        let judge = (SHADING_MAX_SUPPORT, &turns);
        let before = kept.len();
        let (turned, light) = super::shading::judge_by_shading(models, (scene, p), ev, judge, (&mut kept, &unpolished));
        super::polish::polish_those(models, (scene, p), ev, &mut kept, &turned);
        if let Some(light) = light {
            let shown = p.table.as_ref().and_then(|t| super::contrast::Shown::measure(light, models, &kept, ev, t));
            let again = match (kept.len() < before, shown.as_ref()) {
                (true, shown) => Some(Again::All(shown)),
                (false, Some(shown)) => {
                    // Only the faint starts with an edge the light leaves dim can fare otherwise
                    // (none, mostly, under a light from behind the cameras: then nothing runs).
                    let dim: Vec<Vec<Isometry3<f64>>> = models
                        .iter()
                        .zip(&faint)
                        .map(|(m, f)| f.iter().filter(|s| shown.dim_lines(m, s).contains(&true)).copied().collect())
                        .collect();
                    dim.iter().any(|f| !f.is_empty()).then_some(Again::Faint(dim, shown))
                }
                _ => None,
            };
            if let Some(again) = again {
                look_again_from_the_image(models, (scene, p), ev, (&light, again), &mut kept);
            }
        }
    }
    // What the image shows beyond a report moves with it: judged again where it now lies.
    if let Some(ev) = image.filter(|ev| !ev.lines.is_empty()) {
        let larger = super::superset::settle_larger_once_polished(models, (scene, p), ev, &mut kept);
        let covering = super::covering::settle_covered_once_polished(models, (scene, p), ev, &mut kept);
        let replaced: Vec<bool> = larger.iter().zip(&covering).map(|(a, b)| *a || *b).collect();
        super::polish::polish_those(models, (scene, p), ev, &mut kept, &replaced);
    }
    if let Some(table) = p.table.as_ref().filter(|_| image.is_some()) {
        super::table::drop_floating_or_sunk(models, table, &mut kept);
    }
    super::overlap::drop_the_weaker(models, &mut kept, |m, l| matched_length(m, l, scene, p) * l.image_support.sqrt());
    kept
}

/// How the image look looks again once the light is known.
enum Again<'f> {
    /// From every image corner, judged on the edges the light lets show where it is known.
    All(Option<&'f super::contrast::Shown>),
    /// From the first image look's faint starts with an edge the light leaves dim (per model),
    /// judged so.
    Faint(Vec<Vec<Isometry3<f64>>>, &'f super::contrast::Shown),
}

/// The image look again once the shading check has fitted a light: in full where the check
/// dropped reports, and otherwise on the first look's starts that too few edgels bore out,
/// judged on the edges the light lets show ([`super::contrast`]).
///
/// Where reports were dropped, a reading a few degrees off, or of another model, had explained
/// the image lines of the part that is there, and the image look passed over them
/// (`side_light.toml` seed 42: a wedge read 7 deg off, its slope 10% darker than the light has
/// it, dropped; read again from the image, 0.1 deg off). On the tuning seeds (`marvin eval
/// locate`, `widgets.toml` 1-500, `dense.toml` and `side_light.toml` 1-200) this located
/// 98.35 / 92.53 / 95.61% -> 98.50 / 93.21 / 95.76%, with the same 5 / 14 / 2 false reports.
///
/// Otherwise the first image look's starts that too few edgels bore out are judged again on
/// the edges the light lets show, those with an edge it leaves dim: under a light from the
/// side a part standing on the table shows its lit top, while its camera-facing sides show
/// the ambient term alone, the table's grey, and were held to edges no image shows
/// (`side_light.toml` seed 69: a block standing, its image support 0.82 of its whole outline
/// at its true pose). On the tuning seeds this located 98.50 / 93.21 / 95.76% -> 98.53 /
/// 93.53 / 97.55%, with the same false reports; the same as running the whole image look
/// again with the light, at a tenth of its cost (about 0.05 ms of `marvin bench vision`'s
/// match, where the whole look again took 0.4).
///
/// What it finds must show the light as the reports the check let stand do
/// ([`super::shading::fits_light`]): the image look's own bars do not tell an L-bracket from
/// the U-channel it lies on (`widgets.toml` seed 349, without that test).
fn look_again_from_the_image(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    (light, again): (&super::light::Light, Again),
    kept: &mut Vec<Located>,
) {
    use rayon::prelude::*;
    let mut claimed = vec![false; scene.len()];
    for j in kept.iter().flat_map(|l| &l.scene_lines) {
        claimed[*j] = true;
    }
    let found = match again {
        Again::All(shown) => image_look(models, (scene, p), ev, kept, &claimed, shown).0,
        Again::Faint(faint, shown) => {
            let explained = explained_by(models, kept, ev);
            let located = super::image_look::LocatedSolids::new(models, kept, ev);
            models
                .par_iter()
                .zip(&faint)
                .filter(|(_, f)| !f.is_empty())
                .filter_map(|(m, f)| {
                    super::image_look::rejudge(m, (scene, &claimed), p, ev, (f, &located, &explained), shown)
                })
                .collect()
        }
    };
    let first_new = kept.len();
    resolve(models, (scene, p), found, kept, &mut claimed, Some(ev));
    // What it finds faces the rival rule, as the first looks' reports did.
    for i in first_new..kept.len() {
        if let Some(rival) = rival_reading(models, scene, p, ev, kept, i) {
            kept[i] = rival;
        }
    }
    super::superset::settle_larger(models, (scene, p), ev, super::superset::MAX_SUPPORT, kept, first_new);
    super::covering::settle_covered(models, (scene, p), ev, kept, first_new);
    let mut i = first_new;
    while i < kept.len() {
        if super::shading::fits_light(models, ev, (light, RIVAL_MAX_SUPPORT), kept, i) {
            i += 1;
        } else {
            kept.remove(i);
        }
    }
}

/// Every model's image look ([`super::image_look`]) with the objects `kept` so far, on the
/// lines not `claimed`, judged on the edges the light lets show where `shown` says which:
/// what it finds, and each model's starts given up for want of edgels. Nothing without the
/// table or the right image.
fn image_look(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    kept: &[Located],
    claimed: &[bool],
    shown: Option<&super::contrast::Shown>,
) -> (Vec<Located>, Vec<Vec<Isometry3<f64>>>) {
    use rayon::prelude::*;
    if p.table.is_none() || ev.right.is_none() {
        return (Vec::new(), Vec::new());
    }
    let explained = explained_by(models, kept, ev);
    let corners = super::image_look::image_corners(ev, &explained);
    let located = super::image_look::LocatedSolids::new(models, kept, ev);
    let looks: Vec<(Option<Located>, Vec<Isometry3<f64>>)> = models
        .par_iter()
        .map(|m| super::image_look::locate(m, (scene, claimed), p, ev, (&corners, &located, &explained), shown))
        .collect();
    let (found, faint): (Vec<_>, Vec<_>) = looks.into_iter().unzip();
    (found.into_iter().flatten().collect(), faint)
}

/// Each model's first look ([`locate_from`]), in parallel, the dearest begun first: each
/// thread takes the next model of the list ordered so (each look's own parallel parts stay
/// open to idle threads). The looks are independent, but taken in the library's order the
/// dearest (the widget, with the most focus pairs) came last and ran on alone for a millisecond
/// of the 6 ms on two threads (`marvin bench vision`'s scene); rayon's halving of the list
/// ordered by cost still left a model to run alone. Cost is put at the number of focus pairs,
/// once tabled.
fn first_looks(
    models: &[MatcherModel],
    scene: &[Seg],
    pairs: &ScenePairs,
    p: &MatchParams,
    image: Option<&ImageEvidence>,
) -> Vec<Search> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let focus_pairs = |m: &MatcherModel| m.views.get().map_or(0, |(_, views)| views.iter().map(Vec::len).sum());
    let mut order: Vec<usize> = (0..models.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(focus_pairs(&models[i])));
    let (next, done) = (AtomicUsize::new(0), std::sync::Mutex::new(Vec::with_capacity(models.len())));
    rayon::scope(|s| {
        for _ in 0..rayon::current_num_threads().min(models.len()) {
            s.spawn(|_| {
                while let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) {
                    let search = locate_from(&models[i], scene, pairs, p, image);
                    done.lock().expect("no first look panics holding the lock").push((i, search));
                }
            });
        }
    });
    let mut done = done.into_inner().expect("no first look panicked holding the lock");
    done.sort_by_key(|(i, _)| *i);
    done.into_iter().map(|(_, search)| search).collect()
}

/// A reading of another model that explains report `i`'s object better than it does: sought
/// by the second look from that report's 3D lines (the lines of the other reports still
/// claimed) and the image lines no other report explains, its centre within the report's
/// bounding sphere, it must fill the report's space, run
/// along edgels for [`RIVAL_MIN_IMAGE_SUPPORT`] of its camera-facing wireframe with nothing
/// excused as hidden, and explain more of the image than the report: a larger share of its
/// wireframe along edgels and more wireframe in all (px). Only reports on little 3D evidence
/// ([`RIVAL_MAX_SUPPORT`]) are challenged, however well the image bears them out. (A first
/// version spared those borne out along 95% of their wireframe or more, for speed; a reporting
/// seed, 10011, showed a bracket at 95.5% picked for a channel. On tuning seeds, `eval locate`
/// of `widgets.toml` 1-50 and `dense.toml` 1-30, both presets, sparing them changes no report.)
///
/// Why: an L-bracket is a U-channel with an arm missing, and where the channel's third arm has
/// its long edges along the rasters stereo gives it no 3D line; the bracket then explains the
/// 3D lines as well as the channel does (better: the channel's pose from the second look rests
/// on fewer of them), and the first look, which sees only 3D lines, reports the bracket. The
/// image shows the arm: the bracket's wireframe runs along 72% of edgels, the channel's 100%
/// and a third more of it (seed 13, a lone channel, picked as a bracket).
fn rival_reading(
    models: &[MatcherModel],
    scene: &[Seg],
    p: &MatchParams,
    ev: &ImageEvidence,
    kept: &[Located],
    i: usize,
) -> Option<Located> {
    let r = &kept[i];
    if r.support_fraction >= RIVAL_MAX_SUPPORT {
        return None;
    }
    let own = models.iter().find(|m| m.name == r.model)?;
    let others: Vec<Located> = kept.iter().enumerate().filter(|(k, _)| *k != i).map(|(_, l)| l.clone()).collect();
    let mut claimed = vec![false; scene.len()];
    for j in others.iter().flat_map(|l| &l.scene_lines) {
        claimed[*j] = true;
    }
    for &j in &r.scene_lines {
        claimed[j] = false;
    }
    // Nothing excused as hidden: a rival must show the image all of its wireframe.
    let (solids, explained) = (Vec::new(), explained_by(models, &others, ev));
    // Image lines another report explains would seed a reading of that object, not of this one.
    let unexplained: Vec<_> = ev.lines.iter().filter(|l| explained.share_of_line(l) < 0.5).copied().collect();
    if unexplained.is_empty() {
        return None;
    }
    let ev = &ev.with_lines(unexplained);
    // A rival must end with a larger share along edgels than the report's; before it is
    // refined it may fall short of that by RIVAL_REFINE_GAIN.
    let min_to_refine = RIVAL_MIN_TO_REFINE.max(r.image_support - RIVAL_REFINE_GAIN);
    // A reading of the same object lies where the report does: its centre within the report's
    // bounding sphere.
    let (centre, radius) = own.bounding_sphere();
    let sphere = (r.cam_from_model * centre, radius);
    let explains =
        |m: &MatcherModel, l: &Located| l.image_support * super::verify::facing_length_px(m, &l.cam_from_model, ev.cam);
    let own_explains = explains(own, r);
    use rayon::prelude::*;
    models
        .par_iter()
        .filter(|m| m.name != r.model)
        .flat_map_iter(|m| {
            super::second_look::locate_refining(
                m,
                scene,
                &claimed,
                p,
                ev,
                (&solids, &explained),
                (min_to_refine, Some(sphere)),
            )
            .into_iter()
            .map(move |l| (m, l))
        })
        .filter(|(m, l)| {
            fill_the_same_space(m, &l.cam_from_model, own, &r.cam_from_model)
                && !through_table(p.table.as_ref(), m, &l.cam_from_model)
                && l.image_support > r.image_support
                && super::verify::image_support_at_least(m, &l.cam_from_model, ev, RIVAL_MIN_IMAGE_SUPPORT).is_some()
                && explains(m, l) > own_explains
                && admissible(models, l, &others, &claimed)
        })
        .max_by(|a, b| explains(a.0, &a.1).total_cmp(&explains(b.0, &b.1)))
        .map(|(_, l)| l)
}

/// A rival reading must run along edgels for this share of its camera-facing wireframe, none
/// of it excused as hidden (the second look's bar for a pose on one 3D line).
const RIVAL_MIN_IMAGE_SUPPORT: f64 = 0.85;
/// Only reports on little 3D evidence are set against rivals: under this share of their
/// model's length matched by 3D lines (the first look asks 0.15; of the 7 false reports on
/// tuning seeds 1-50, 2001-2050 and 3001-3050, 5 had 0.14-0.29). A search for rivals costs
/// 1-7 ms a report challenged (10 ms before the candidates were sifted).
const RIVAL_MAX_SUPPORT: f64 = 0.3;

/// Reports under this share of their model's length along 3D lines are judged by their faces'
/// shading against the scene's light ([`super::shading::judge_by_shading`]): dropped or turned
/// where their faces disagree with it. None is, now: the light is still fitted, for the
/// contrast check and the image look again. Once the channel beyond a bracket was judged in the
/// realistic cell (`superset`), the judge dropped more right readings than wrong ones, on
/// tuning seeds (`marvin eval locate`, realistic `widgets.toml` 1-100 / 101-300 and `dense.toml`
/// 1-60 through tuning seed 1's calibrations, ideal `widgets.toml` 1-100 and `dense.toml` 1-60;
/// located, false reports): 0.3 (the rivals' bar, as before) 96.96% / 96.17% / 88.10% / 98.70%
/// / 94.03% with 3 / 8 / 16 / 2 / 13; 0.2 97.83% / 97.25% / 90.87% / 98.70% / 94.15% with 3 /
/// 8 / 16 / 2 / 13; none 97.83% / 97.69% / 91.71% / 98.70% / 94.27% with 3 / 8 / 18 / 2 / 13.
/// A right U-channel on 8 lines (dense seed 29, 0.29 of its length, image 0.86) was dropped by
/// it. Looking again after the light is fitted still judges its own finds by it
/// ([`RIVAL_MAX_SUPPORT`]).
const SHADING_MAX_SUPPORT: f64 = 0.0;
/// A rival's pose is refined only if it already runs along edgels for this share of its
/// wireframe (the second look's own bar is 0.6).
const RIVAL_MIN_TO_REFINE: f64 = 0.75;
/// How much a second look's pose gains along edgels, at most, by its refinement on the image.
const RIVAL_REFINE_GAIN: f64 = 0.15;

/// The image edges of the objects located.
pub(crate) fn explained_by(models: &[MatcherModel], kept: &[Located], ev: &ImageEvidence) -> Explained {
    let located = kept.iter().filter_map(|l| Some((models.iter().find(|m| m.name == l.model)?, &l.cam_from_model)));
    Explained::of(located, ev.cam)
}

/// The objects located, as solids that may hide other objects' parts.
pub(crate) fn solids_of(models: &[MatcherModel], kept: &[Located]) -> Vec<Solid> {
    kept.iter()
        .filter_map(|l| {
            let model = models.iter().find(|m| m.name == l.model)?;
            Some(Solid::new(model, &l.cam_from_model))
        })
        .collect()
}

/// Candidates that had the 3D evidence but too little of their wireframe ran along edgels,
/// checked again on the part of it that nothing hides: neither the objects located (wherever
/// they stand nearer the camera) nor the model's own bulk. A part lying partly behind another
/// can show only what is left in view, and a channel hides its own inner edges; counted as
/// unseen, those parts failed objects that were otherwise well supported (50 scenes: located
/// 0.942 -> 0.948, and one more object on each of seeds 51-80 and 81-110, with the same false
/// reports). Every candidate that passes goes to the merge, which keeps the best of those that
/// share lines or space: taking only each model's best supported one, as at first, left a
/// part's right reading behind a wrong one of the same model, and in a pile the second copy
/// (tuning seeds, `marvin eval locate`, `widgets.toml` 1-500: 96.9% -> 97.1% located, 20 -> 18
/// false reports; `dense.toml` 1-200: 88.2% -> 88.2%, 27 -> 27, two objects fewer;
/// `side_light.toml` 1-200 the same).
pub(crate) fn hidden_in_part(
    models: &[MatcherModel],
    searches: &[Search],
    (kept, claimed): (&[Located], &[bool]),
    p: &MatchParams,
    ev: &ImageEvidence,
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
            let own = Solid::new(model, &c.pose);
            let hiding: Vec<&Solid> = solids.iter().chain([&own]).collect();
            let (image_support, unhidden) = image_support_unhidden(model, &c.pose, ev, &hiding);
            if image_support >= p.min_image_support
                && unhidden >= MIN_IN_VIEW
                && explained.share(model, &c.pose, ev.cam) <= MAX_EXPLAINED
            {
                loc.image_support = image_support;
                out.push(loc);
            }
        }
    }
    out
}

/// Adds `reports` to `kept`, best first, unless one reuses over 30% of lines already claimed,
/// fills space a kept object fills or cuts into the table ([`super::table`]); claims the lines
/// of those it keeps.
///
/// Best is the most evidence explained: [`matched_length`] times the square root of the share
/// of the camera-facing wireframe along edgels. (The share itself weighed a larger model whose
/// extra part another object hides too heavily: on tuning seed 2006 an L-bracket, 0.165 m of 3D
/// lines and 81% along edgels, beat the U-channel it lay in, 0.188 m and 68%. Over 450 tuning
/// scenes, `widgets.toml` seeds 1-50, 101-200, 2001-2050, 3001-3050 and `dense.toml` and
/// `side_light.toml` 1-50 and 2001-2050, the root changed that scene alone; a fourth root the
/// same; on the first 300 of them the share squared located 4 fewer objects with 4 more false
/// reports, and the share left out 8 fewer with 9 more.) What an object kept hides cannot
/// count against a report, so after each one kept the reports it may hide have their share counted again over
/// the part still in view (a U-channel with an arm under a block is judged on the rest of it).
/// A report of another model on as much 3D evidence that the image bears out where the two
/// differ is kept in the best's place ([`super::ties`]), and a report the camera saw through
/// is not kept ([`super::see_through`]).
pub(crate) fn resolve(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    reports: Vec<Located>,
    kept: &mut Vec<Located>,
    claimed: &mut [bool],
    image: Option<&ImageEvidence>,
) {
    struct Pending<'m> {
        loc: Located,
        model: &'m MatcherModel,
        solid: Solid,
        matched: f64,
        score: f64,
    }
    let mut pending: Vec<Pending> = reports
        .into_iter()
        .filter_map(|loc| {
            let model = models.iter().find(|m| m.name == loc.model)?;
            if through_table(p.table.as_ref(), model, &loc.cam_from_model) {
                return None;
            }
            let (solid, matched) = (Solid::new(model, &loc.cam_from_model), matched_length(model, &loc, scene, p));
            Some(Pending { loc, model, solid, matched, score: 0.0 })
        })
        .collect();
    impl TieCandidate for Pending<'_> {
        fn parts(&self) -> (&MatcherModel, &Located, f64) {
            (self.model, &self.loc, self.matched)
        }
    }
    let mut solids = solids_of(models, kept);
    let mut newest: Option<usize> = None;
    loop {
        pending.retain(|r| admissible(models, &r.loc, kept, claimed));
        for r in pending.iter_mut() {
            let share = match (image, newest) {
                // Judged again only where the object just kept may hide some of it.
                (Some(ev), Some(k)) if solids[k].may_hide(&r.solid) => {
                    let hiding: Vec<&Solid> = solids.iter().filter(|s| s.may_hide(&r.solid)).collect();
                    image_support_unhidden(r.model, &r.loc.cam_from_model, ev, &hiding).0
                }
                (_, Some(_)) => continue,
                (_, None) => r.loc.image_support,
            };
            r.score = r.matched * share.sqrt();
        }
        let best = pending.iter().enumerate().max_by(|a, b| a.1.score.total_cmp(&b.1.score).then(b.0.cmp(&a.0)));
        let Some((i, _)) = best else { break };
        let i = match image {
            Some(ev) => settle_tie(&pending, i, (kept, &solids), models, ev),
            None => i,
        };
        let r = pending.remove(i);
        if image.is_some_and(|ev| {
            super::see_through::seen_through(r.model, &r.loc.cam_from_model, ev).is_some_and(|s| s.refutes())
        }) {
            continue;
        }
        for &j in &r.loc.scene_lines {
            claimed[j] = true;
        }
        kept.push(r.loc);
        solids.push(r.solid);
        newest = Some(solids.len() - 1);
    }
}

/// Of the pending reports, the one to keep: the best (`best`), or a report of another model
/// that fills the same space on as much 3D evidence ([`super::ties::TIE`]) where the image
/// shows its own edges clearly better than the best's ([`super::ties::gain_where_apart`]),
/// none hidden by `solids` or explained by `kept`.
fn settle_tie<P: TieCandidate>(
    pending: &[P],
    best: usize,
    (kept, solids): (&[Located], &[Solid]),
    models: &[MatcherModel],
    ev: &ImageEvidence,
) -> usize {
    let (b_model, b_loc, b_matched) = pending[best].parts();
    let b_pose = &b_loc.cam_from_model;
    let rivals: Vec<usize> = (0..pending.len())
        .filter(|&j| {
            let (q_model, q_loc, q_matched) = pending[j].parts();
            let q_pose = &q_loc.cam_from_model;
            j != best
                && q_model.name != b_model.name
                && q_matched >= super::ties::TIE * b_matched
                && fill_the_same_space(q_model, q_pose, b_model, b_pose)
        })
        .collect();
    if rivals.is_empty() {
        return best;
    }
    let hiding: Vec<&Solid> = solids.iter().collect();
    let explained = explained_by(models, kept, ev);
    rivals
        .into_iter()
        .filter_map(|j| {
            let (q_model, q_loc, _) = pending[j].parts();
            let readings = ((b_model, b_pose), (q_model, &q_loc.cam_from_model));
            super::ties::gain_where_apart(readings, ev, &hiding, &explained).map(|gain| (j, gain))
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(best, |(j, _)| j)
}

/// What [`settle_tie`] reads off a pending report: its model, the report, its 3D length matched.
trait TieCandidate {
    fn parts(&self) -> (&MatcherModel, &Located, f64);
}

/// The 3D length a report matches, less [`OVERRUN_WEIGHT`] times the length of its lines that
/// runs on past its edges' ends.
///
/// A scene line along a model edge that runs on past the edge's end says the object there is
/// longer than the model: an L-bracket read into a U-channel whose second arm another part
/// hides matches the channel's lines about as well as the channel does (an L is a U with one
/// arm missing), but the channel's web runs on past the bracket's end. On seeds 2001-2050 four
/// such readings ran on by 8-12 mm; parts truly there mostly by nothing, but two L-brackets by
/// 7-8 mm (lines merged with a neighbour's), so it weighs in the balance and rejects nothing.
pub(crate) fn matched_length(model: &MatcherModel, l: &Located, scene: &[Seg], p: &MatchParams) -> f64 {
    let pairs = super::support::correspondences_at(model, &l.cam_from_model, scene, p);
    (l.support - OVERRUN_WEIGHT * super::support::overrun(&pairs, scene)).max(0.0)
}

/// How much a metre of scene line running on past a model edge's end counts against a report,
/// in metres matched.
///
/// Chosen on tuning seeds of `widgets.toml` (`marvin eval locate --scenes 50`, located and
/// false reports on seeds from 1 / 2001 / 3001): ranked by 3D length times the image's share
/// as before, 0.957 / 0.937 / 0.963 and 2 / 6 / 2; judged again as objects are kept (weight 0),
/// 0.957 / 0.942 / 0.963 and 2 / 4 / 2; weight 2, 0.957 / 0.945 / 0.963 and 2 / 3 / 2; 5 and
/// 10 lose seed 38's L-bracket to a pose of it 5 mm off. `dense.toml` seeds 2001-2020: the same
/// 0.827 and 5 false reports for 2 as before.
pub(crate) const OVERRUN_WEIGHT: f64 = 2.0;

/// Whether a report may join those `kept`: no more than 30% of its lines `claimed` by them (else
/// its evidence is another object's), and sharing little space with any of them (solids cannot).
/// Space is judged on the solids themselves, not on spheres round them: a part nestled in a
/// U-channel's mouth lies near the channel's centre but fills none of its space (judged by
/// centres, a T-piece found at 0.2 mm was turned away on seed 96).
pub(crate) fn admissible(models: &[MatcherModel], loc: &Located, kept: &[Located], claimed: &[bool]) -> bool {
    let shared = loc.scene_lines.iter().filter(|&&j| claimed[j]).count();
    if shared * 10 > loc.scene_lines.len() * 3 {
        return false;
    }
    let model_of = |name: &str| models.iter().find(|m| m.name == name);
    let Some(model) = model_of(&loc.model) else { return true };
    !kept.iter().any(|k| {
        model_of(&k.model)
            .is_some_and(|other| fill_the_same_space(model, &loc.cam_from_model, other, &k.cam_from_model))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::overlap::space_shared;

    /// A U-channel with one arm's lines missing (hidden) is an L-bracket's shape too: both
    /// matchers report it, and the merge keeps the channel, which explains more of the lines
    /// (its web runs on past the bracket's end).
    #[test]
    fn a_channel_missing_an_arm_is_not_taken_for_a_bracket() {
        let (bracket, channel) =
            (crate::matcher::fixtures::model("l_bracket"), crate::matcher::fixtures::model("u_channel"));
        let pose = Isometry3::from_parts(
            nalgebra::Translation3::new(0.02, -0.01, 0.85),
            nalgebra::UnitQuaternion::from_euler_angles(0.4, -0.3, 0.8),
        );
        // The profile's right arm (x > 25 mm) hidden: only lines with an end left of it stay.
        let scene: Vec<Seg> = (0..channel.lines.len())
            .filter(|&k| channel.faces_camera(k, &pose))
            .map(|k| &channel.lines[k])
            .filter(|l| l.a.x.min(l.b.x) < 0.024)
            .map(|l| l.transformed(&pose))
            .collect();
        let p = MatchParams::default();
        let found = locate_all(&[bracket, channel], &scene, &p, None);
        let names: Vec<&str> = found.iter().map(|l| l.model.as_str()).collect();
        assert_eq!(names, ["u_channel"], "{names:?}");
        assert!((found[0].cam_from_model.translation.vector - pose.translation.vector).norm() < 1e-3);
    }

    /// A U-channel whose 3D lines stereo gave only round one corner (the web's inner edge short
    /// of the far arm, the near arm's outer edge, the upright between them: an L-bracket's
    /// corner too, and the channel's lines too few for the first look) while the image shows
    /// all of it: the
    /// bracket fits the 3D lines and is reported first, and the channel, read again from those
    /// lines by the second look, explains the image better and stands instead.
    #[test]
    fn a_channel_the_image_shows_whole_is_not_taken_for_a_bracket() {
        let (bracket, channel) =
            (crate::matcher::fixtures::model("l_bracket"), crate::matcher::fixtures::model("u_channel"));
        let cam = crate::matcher::fixtures::camera_at(nalgebra::Point3::new(0.0, -0.6, 0.6));
        let world_from_model = Isometry3::from_parts(
            nalgebra::Translation3::new(0.01, -0.02, 0.0125),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
        );
        let pose = cam.cam_from_world() * world_from_model;
        let top = channel.lines.iter().map(|l| l.a.z.max(l.b.z)).fold(f64::MIN, f64::max);
        let near = |a: f64, b: f64| (a - b).abs() < 1e-6;
        let corner = |l: &&Seg| {
            let on_top = near(l.a.z, top) && near(l.b.z, top);
            let web = on_top && near(l.a.y, -0.01) && near(l.b.y, -0.01);
            let arm = on_top && near(l.a.x, -0.04) && near(l.b.x, -0.04);
            let upright = near(l.a.x, -0.04) && near(l.b.x, -0.04) && near(l.a.y, -0.025) && near(l.b.y, -0.025);
            web || arm || upright
        };
        // The web's line stops 5 mm short of the far arm.
        let clipped = |l: &Seg| {
            let (a, b) = if l.a.x < l.b.x { (l.a, l.b) } else { (l.b, l.a) };
            if near(a.y, b.y) && near(a.z, b.z) && b.x > 0.02 {
                Seg::new(a, nalgebra::Point3::new(0.02, b.y, b.z))
            } else {
                *l
            }
        };
        let scene: Vec<Seg> = channel.lines.iter().filter(corner).map(|l| clipped(l).transformed(&pose)).collect();
        assert_eq!(scene.len(), 3);
        let (edges, lines) = crate::matcher::verify::drawn::model_edges(&channel, &pose, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines);
        let p = MatchParams::default();
        let bracket_alone = locate_all(std::slice::from_ref(&bracket), &scene, &p, Some(&ev));
        assert_eq!(bracket_alone.len(), 1, "the bracket fits the 3D lines");
        let found = locate_all(&[bracket, channel], &scene, &p, Some(&ev));
        let names: Vec<&str> = found.iter().map(|l| l.model.as_str()).collect();
        assert_eq!(names, ["u_channel"], "{names:?}");
        assert!((found[0].cam_from_model.translation.vector - pose.translation.vector).norm() < 2e-3);
    }

    /// Solids may not share space: the same block a millimetre off shares nearly all of it, a
    /// block beside it none, and a T-piece whose stem stands in a U-channel's mouth none either,
    /// though their centres nearly coincide (as they would for one object inside another).
    #[test]
    fn reports_may_not_fill_the_same_space() {
        let (block, channel, tee) = (
            crate::matcher::fixtures::model("block"),
            crate::matcher::fixtures::model("u_channel"),
            crate::matcher::fixtures::model("t_piece"),
        );
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
