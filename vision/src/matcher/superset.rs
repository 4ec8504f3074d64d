//! A part read as a smaller model that its own shape holds: an L-bracket is a U-channel with one
//! arm missing. Where the channel's third arm gives stereo no 3D line (its long edges along the
//! rasters, or hidden in part), a bracket reading lies along the channel's 3D lines and edgels,
//! and on little 3D evidence it may be all that is reported there. What tells them apart is
//! whether the image shows the larger model's extra edges where they would be, never how bright
//! the faces are: the matcher does not know a part's material (issue 48).
//!
//! Where a larger model fits around a smaller one is found by the matcher itself, once per pair
//! of models: the larger model's search run on the smaller one's wireframe as its scene.

use super::model::{Located, MatchParams, MatcherModel, Seg};
use super::occlusion::Solid;
use super::verify::{Beyond, ImageEvidence, image_support_beyond};
use nalgebra::{Isometry3, Point3, Vector3};
use std::collections::HashMap;
use std::sync::{Mutex, OnceLock};

/// A larger model holds a smaller one where the smaller one, sought among the larger one's
/// lines, finds this share of its length along them or more. An L-bracket finds 0.86 along a
/// U-channel's (its bar is 10 mm shorter than the channel's, and its end face lies inside it).
const HOLDS: f64 = 0.8;
/// ...and only if its wireframe is this much longer (else neither holds the other).
const LARGER_BY: f64 = 1.1;
/// The image shows the larger model beyond the report where its wireframe further than
/// [`APART_PX`] from the report's runs along edgels for this share of that length or more
/// (what the larger model's own body or the other reports hide, and the other reports' own
/// edges, left out). Chosen on tuning seeds in the realistic cell, where a channel's faces and
/// the table can show the same grey and the extra arm's outline is faint: of the
/// low-support L-brackets reported on `widgets.toml` seeds 101-300, the 46 right ones showed
/// a channel beyond them on at most 0.28 of its length (0.42 before the other reports' edges
/// were left out), the 7 read on a channel on 0.32-0.67 (and one on none). `marvin eval
/// locate` (realistic `widgets.toml` 1-100 / 101-300, `dense.toml` 1-60; ideal `widgets.toml`
/// 1-100, `dense.toml` 1-60; located, false reports): 0.75 gave 96.96% / 95.66% / 87.98% /
/// 98.70% / 93.91% with 3 / 15 / 17 / 2 / 14; 0.5 the same but 95.95% / 11 on 101-300 and
/// 94.03% / 13 on ideal dense; 0.4 96.96% / 96.02% / 88.10% / 98.70% / 94.03% with 3 / 10 /
/// 16 / 2 / 13; 0.3 lost three right brackets on 1-100 (96.53%, 4).
const SHOWN_BEYOND: f64 = 0.4;
/// ...over at least this length (pixels).
const MIN_BEYOND_PX: f64 = 20.0;
/// Where the report's own edges that the larger model lacks (an L-bracket's bar end, inside a
/// channel's bar) are in view for [`MIN_OWN_PX`] or more and run along edgels for no more than
/// [`OWN_UNSHOWN`] of it, the image shows nothing that the smaller model has and the larger
/// lacks, and the larger model shows beyond it at this lower share: the larger model's faint
/// edges (a channel's inner faces in their own shadow) are then the better account, unless
/// something else fills the room it would take. On realistic `dense.toml` tuning seeds 1-200,
/// of the L-brackets asked whose bar end shows so little, the five read on a U-channel showed
/// the channel beyond on 0.13-0.36; the three right ones on 0.02 and 0.05 (and one where a
/// neighbour takes the channel's room). `marvin eval locate` through tuning seed 1's
/// calibrations (located, false reports): realistic `dense.toml` 1-60 92.43% / 8 → 92.55% / 7,
/// 61-200 90.89% / 20 → 91.09% / 16, realistic `widgets.toml` 301-700 98.20% / 9 → 98.23% / 8;
/// realistic `widgets.toml` 1-300 and 701-1100, ideal `widgets.toml` 1-100 and `dense.toml`
/// 1-160 the same false reports as before.
const SHOWN_BESIDE_NOTHING: f64 = 0.1;
/// Where the report's own edges beyond the larger model's are out of view (other parts hide
/// [`MIN_OWN_PX`] or more of them, and the image shows none), the image says nothing for the
/// smaller model, and the larger model shows beyond it at this share, nothing filling any of
/// its room: higher than [`SHOWN_BESIDE_NOTHING`], as nothing speaks against the report either.
/// On tuning seeds, of the L-brackets asked whose bar end was hidden so, the right ones showed
/// a channel beyond them on at most 0.11 of its edges (realistic `dense.toml` 1-200,
/// `widgets.toml` 1-300) and on 0.26 where a neighbour took some of the channel's room (ideal
/// `dense.toml` seed 112); the brackets read on a channel on 0.17-0.29 (realistic `widgets.toml`
/// seeds 520, 885 and 989; 885's channel then read turned over), or on 0.06 and 0.14 (seed 533
/// and dense seed 144, still reported). `marvin eval locate` as for [`SHOWN_BESIDE_NOTHING`]:
/// realistic `widgets.toml` 301-700 98.23% / 8 → 98.27% / 7, 701-1100 98.41% / 15 → 98.41% / 14;
/// ideal `dense.toml` 1-160 unchanged (94.01% / 20; 93.97% had the room not been asked).
const SHOWN_BESIDE_HIDDEN: f64 = 0.15;
/// ...the report's own edges beyond the larger model's in view over at least this length (pixels)...
const MIN_OWN_PX: f64 = 10.0;
/// ...and along edgels for no more than this share of it.
const OWN_UNSHOWN: f64 = 0.1;
/// Reports with less than this share of their model's length along 3D lines are asked whether
/// a larger model shows beyond them. It was the rivals' bar (0.3); a bracket read on a channel
/// can rest on more (0.32 and 0.50 on realistic `widgets.toml` tuning seeds 278 and 267).
/// `marvin eval locate` as for [`SHOWN_BEYOND`]: 0.45 96.10% / 9 false on seeds 101-300, 0.6
/// 96.17% / 8, and every report (1.0) the same as 0.6; nothing else changed on any of the five
/// sets.
pub(crate) const MAX_SUPPORT: f64 = 0.6;
/// How far (pixels) from the report's projected wireframe the larger model's counts as beyond it.
const APART_PX: f64 = 3.0;

/// Poses of `outer` in `inner`'s model frame at which `outer`'s wireframe runs along
/// [`HOLDS`] of `inner`'s (`inner_from_outer`), where `outer` is the larger by [`LARGER_BY`].
pub(crate) fn holding_poses(inner: &MatcherModel, outer: &MatcherModel, p: &MatchParams) -> Vec<Isometry3<f64>> {
    if outer.total_length < LARGER_BY * inner.total_length {
        return Vec::new();
    }
    poses_along(inner, outer, p, HOLDS)
}

/// Poses of `outer` in `inner`'s model frame (`inner_from_outer`) at which `inner`, sought
/// among `outer`'s lines by its own search, finds `share` of its length along them or more;
/// found once per pair of models (by name and length) and share, and kept.
pub(crate) fn poses_along(
    inner: &MatcherModel,
    outer: &MatcherModel,
    p: &MatchParams,
    share: f64,
) -> Vec<Isometry3<f64>> {
    type Key = (String, String, u64, u64, u64);
    static KNOWN: OnceLock<Mutex<HashMap<Key, Vec<Isometry3<f64>>>>> = OnceLock::new();
    let lengths = (inner.total_length.to_bits(), outer.total_length.to_bits());
    let key = (inner.name.clone(), outer.name.clone(), lengths.0, lengths.1, share.to_bits());
    let known = KNOWN.get_or_init(Default::default);
    if let Some(poses) = known.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return poses.clone();
    }
    let wireframe: Vec<Seg> = outer.lines.iter().take(outer.first_marking).map(|l| Seg::new(l.a, l.b)).collect();
    let bare = MatchParams { table: None, ..*p };
    let poses: Vec<Isometry3<f64>> = super::search::locate(inner, &wireframe, &bare, None)
        .into_iter()
        .filter(|l| l.support >= share * inner.total_length)
        .map(|l| l.cam_from_model.inverse())
        .collect();
    known.lock().unwrap_or_else(|e| e.into_inner()).insert(key, poses.clone());
    poses
}

/// What to make of report `i` (of `kept`, the others solids that may hide it and edges that
/// explain edgels) where a larger model holds it: the image shows the larger model's edges
/// beyond the report's (along edgels for [`SHOWN_BEYOND`] of [`MIN_BEYOND_PX`] or more, hidden
/// parts and the others' edges left out; for [`SHOWN_BESIDE_NOTHING`] where the report's own
/// edges beyond the larger model's show nothing) at some holding pose. Only reports on little 3D evidence (`max_support` of their model's length) are
/// looked at.
pub(crate) enum Larger {
    /// No larger model shows: the report stands.
    No,
    /// The larger model's reading, refitted on the 3D lines and the image.
    Reading(Located),
    /// A larger model shows, but no reading of it refits (through the table, or on no 3D line):
    /// the report is not what lies there.
    Unfitted,
    /// Where the larger model's extra edges would be, the image shows less than
    /// [`MIN_BEYOND_PX`] of them: other objects hide them or they fall outside the image, and
    /// nothing located fills the room they would take. The report cannot be told from the
    /// larger model and is not made. (On tuning seeds: L-brackets read on U-channels cut by the
    /// image's border or with their third arm under a neighbour; where a right bracket's
    /// channel would have its arm inside a located neighbour, the bracket stands.)
    KeptFromView,
    /// The image shows neither the report's own edges that the larger model lacks nor the
    /// larger model's beyond the report, both in view ([`MIN_OWN_PX`], [`MIN_BEYOND_PX`], along
    /// edgels for no more than [`OWN_UNSHOWN`] and less than the bar), nothing fills the larger
    /// model's room, and stereo does not see through any of its place
    /// ([`super::see_through::SeenThrough::in_part`]): the report rests on what the two share,
    /// and is not made.
    ///
    /// Why: an L-bracket read in a U-channel's corner, the channel's third arm out of sight
    /// (under parts not located, or as grey as what lies behind it), was reported as a bracket
    /// though the bracket's bar end showed nothing either (realistic `dense.toml` tuning seeds
    /// 5063 and 5135: the arm along edgels for 0.00 of 130-140 px, the bar end for 0.00 of
    /// 10-20 px; no matched edgel behind the channel's place). Where a right bracket shows so
    /// little, stereo mostly sees the table through the arm's place (realistic `widgets.toml`
    /// 4535: 22 matched edgels inside the channel's outline, all behind it; 4551: 15 of 29;
    /// `two_lamps.toml` 57: 15 of 63), and it stands. `marvin eval locate` through tuning seed
    /// 1's calibrations (located, false reports): realistic `dense.toml` 5001-5400 0.9250 / 59
    /// -> 0.9246 / 52, `widgets.toml` 4401-4700 0.9799 / 8 -> 0.9794 / 7, `two_lamps.toml` 1-100
    /// unchanged (0.9595 / 4); ideal `dense.toml` 5001-5200 0.9496 / 19 -> 0.9496 / 18,
    /// `widgets.toml` 5001-5200 unchanged (0.9935 / 0). Asking instead that most of the matched
    /// edgels lie behind ([`super::see_through::SeenThrough::refutes`]) gave one false report
    /// fewer on dense and lost three right brackets (two lamps 57, ideal dense 5182, and 6228
    /// of the fresh seeds below); not asking stereo at all lost 4535 and 4551 too. On fresh
    /// tuning seeds, run once after the choice: `dense.toml` 6001-6300 0.9172 / 51 -> 0.9172 /
    /// 50, `widgets.toml` 6001-6300 unchanged (0.9860 / 8).
    Neither,
}

/// How deep (metres) inside another object or under the table a point of the larger model
/// must lie for that model to have no room there: parts rest on each other and on the table,
/// and their located poses are a millimetre or two off.
const ROOM_M: f64 = 0.003;

/// A located object's closed surface (`cam` frame), for telling whether a point lies well
/// inside it.
struct Body {
    triangles: Vec<[Point3<f64>; 3]>,
    centre: Point3<f64>,
    radius: f64,
}

impl Body {
    fn new(model: &MatcherModel, pose: &Isometry3<f64>) -> Body {
        let (centre, radius) = model.bounding_sphere();
        Body { triangles: model.triangles.iter().map(|t| t.map(|q| pose * q)).collect(), centre: pose * centre, radius }
    }

    /// Whether `x` lies inside the surface, [`ROOM_M`] or more from it along each axis.
    fn holds_deep(&self, x: &Point3<f64>) -> bool {
        if (x - self.centre).norm() > self.radius {
            return false;
        }
        let steps = [Vector3::x(), Vector3::y(), Vector3::z()].into_iter().flat_map(|e| [e * ROOM_M, -e * ROOM_M]);
        std::iter::once(Vector3::zeros()).chain(steps).all(|d| mesh::trimesh::encloses(&self.triangles, &(x + d)))
    }
}

/// The reports of `kept` other than `i`, with their models.
pub(crate) fn others_than<'a>(
    models: &'a [MatcherModel],
    kept: &'a [Located],
    i: usize,
) -> Vec<(&'a MatcherModel, &'a Isometry3<f64>)> {
    kept.iter()
        .enumerate()
        .filter(|(k, _)| *k != i)
        .filter_map(|(_, l)| models.iter().find(|m| m.name == l.model).map(|m| (m, &l.cam_from_model)))
        .collect()
}

/// [`Larger`] for report `i` of `kept`.
pub(crate) fn larger_reading(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    (kept, max_support): (&[Located], f64),
    i: usize,
) -> Larger {
    let r = &kept[i];
    let Some(own) = models.iter().find(|m| m.name == r.model) else { return Larger::No };
    if r.support_fraction >= max_support {
        return Larger::No;
    }
    // The larger models' poses round the report: most models have none, and then nothing
    // else need be built.
    let around: Vec<(&MatcherModel, Isometry3<f64>)> = models
        .iter()
        .filter(|m| m.name != own.name)
        .flat_map(|m| holding_poses(own, m, p).into_iter().map(move |t| (m, r.cam_from_model * t)))
        .collect();
    if around.is_empty() {
        return Larger::No;
    }
    let others = others_than(models, kept, i);
    let solids: Vec<Solid> = others.iter().map(|(m, pose)| Solid::new(m, pose)).collect();
    let solids: Vec<&Solid> = solids.iter().collect();
    let explained = super::verify::Explained::of(others.iter().copied(), ev.cam);
    let bodies: Vec<Body> = others.iter().map(|(m, pose)| Body::new(m, pose)).collect();
    let taken =
        |x: &Point3<f64>| p.table.is_some_and(|t| t.height_of(x) < -ROOM_M) || bodies.iter().any(|b| b.holds_deep(x));
    let beyond: Vec<(&MatcherModel, Isometry3<f64>, Beyond)> = around
        .into_iter()
        .map(|(m, pose)| {
            let b =
                image_support_beyond((m, &pose), (own, &r.cam_from_model), ev, &solids, &explained, APART_PX, &taken);
            (m, pose, b)
        })
        .collect();
    // The least share of the larger model's edges beyond the report that shows it, by what
    // the image shows of the report's own edges beyond the larger model's (and, where it shows
    // none of them, whether anything else fills any of the larger model's room).
    let mine = |m: &MatcherModel, pose: &Isometry3<f64>| {
        image_support_beyond((own, &r.cam_from_model), (m, pose), ev, &solids, &explained, APART_PX, &|_| false)
    };
    let bar = |(m, pose, b): (&MatcherModel, &Isometry3<f64>, &Beyond)| {
        let mine = mine(m, pose);
        let seen = mine.share * mine.px;
        if mine.px >= MIN_OWN_PX && mine.share <= OWN_UNSHOWN {
            SHOWN_BESIDE_NOTHING
        } else if mine.px < MIN_OWN_PX && seen == 0.0 && mine.kept_from_view_px >= MIN_OWN_PX && b.taken_px == 0.0 {
            SHOWN_BESIDE_HIDDEN
        } else {
            SHOWN_BEYOND
        }
    };
    let shown: Vec<(&MatcherModel, Isometry3<f64>)> = beyond
        .iter()
        .filter(|(m, pose, b)| {
            b.px >= MIN_BEYOND_PX
                && (b.share >= SHOWN_BEYOND || (b.taken_px < MIN_BEYOND_PX && b.share >= bar((m, pose, b))))
        })
        .map(|(m, pose, _)| (*m, *pose))
        .collect();
    let shows_neither = |(m, pose, b): &(&MatcherModel, Isometry3<f64>, Beyond)| {
        let own_unshown = || {
            let mine = mine(m, pose);
            mine.px >= MIN_OWN_PX && mine.share <= OWN_UNSHOWN
        };
        b.px >= MIN_BEYOND_PX
            && b.taken_px < MIN_BEYOND_PX
            && own_unshown()
            && !super::see_through::seen_through(m, pose, ev).is_some_and(|s| s.in_part())
    };
    if shown.is_empty() && beyond.iter().any(shows_neither) {
        return Larger::Neither;
    }
    if shown.is_empty() {
        let kept_from_view = beyond.iter().any(|(_, _, b)| {
            b.px < MIN_BEYOND_PX && b.kept_from_view_px >= MIN_BEYOND_PX && b.taken_px < MIN_BEYOND_PX
        });
        return if kept_from_view { Larger::KeptFromView } else { Larger::No };
    }
    let turns = super::shading::TurnedCandidates::default();
    shown
        .into_iter()
        .filter_map(|(m, pose)| turns.refit(m, (scene, p), ev, pose).map(|c| c.located(m, c.image_support)))
        .max_by(|a, b| (a.image_support * a.support).total_cmp(&(b.image_support * b.support)))
        .map_or(Larger::Unfitted, Larger::Reading)
}

/// Each report of `kept` from `first` on that a larger model holds ([`larger_reading`]):
/// replaced by the larger model's reading, or dropped where that does not refit.
pub(crate) fn settle_larger(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    max_support: f64,
    kept: &mut Vec<Located>,
    first: usize,
) {
    let mut i = first;
    while i < kept.len() {
        match larger_reading(models, (scene, p), ev, (kept, max_support), i) {
            Larger::No => i += 1,
            Larger::Reading(l) => {
                kept[i] = l;
                i += 1;
            }
            Larger::Unfitted | Larger::KeptFromView | Larger::Neither => {
                kept.remove(i);
            }
        }
    }
}

/// Each report of `kept` judged again by [`larger_reading`] at the pose the polish and the turns
/// leave it, once every look is done; returns which reports were replaced by a larger model's
/// reading (to be polished in turn). Where it shows neither ([`Larger::Neither`]) or the
/// larger model is kept from view ([`Larger::KeptFromView`]) the report is dropped; where the
/// larger model shows beyond it in the left image, it stands instead only if it shows its own
/// edges in the right image too ([`shown_in_the_right_image`]); where it does not refit, the
/// report stands.
///
/// Why: the looks judge a report where they leave it, a few degrees off as often as not, and
/// what the image shows beyond a bracket moves with it. Polished, brackets read on channels
/// show the channel beyond them (realistic `dense.toml` tuning seeds 5100, 5257, 5343: their
/// channels' own edges along edgels for 0.72-1.00 more of their length than the brackets' own,
/// in both images). Judged again so with the left image alone, a right bracket became a
/// channel whose own edges the right image does not show (5136) and three right brackets
/// whose channel did not refit were dropped (5029 ideal, 5276, 6236). As it stands, `marvin
/// eval locate` through tuning seed 1's calibrations (located, false reports): realistic
/// `dense.toml` 5001-5400 0.9246 / 52 -> 0.9251 / 47, 6001-6300 0.9172 / 50 -> 0.9175 / 47;
/// ideal `dense.toml` 5001-5200 0.9496 / 18 -> 0.9500 / 16; realistic `widgets.toml`
/// 4401-4700, `two_lamps.toml` 1-100 and ideal `widgets.toml` 5001-5200 the same reports.
pub(crate) fn settle_larger_once_polished(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    kept: &mut Vec<Located>,
) -> Vec<bool> {
    let mut replaced = vec![false; kept.len()];
    let mut i = 0;
    while i < kept.len() {
        match larger_reading(models, (scene, p), ev, (kept, MAX_SUPPORT), i) {
            Larger::Reading(l) if shown_in_the_right_image(models, ev, kept, i, &l) => {
                kept[i] = l;
                replaced[i] = true;
                i += 1;
            }
            Larger::KeptFromView | Larger::Neither => {
                kept.remove(i);
                replaced.remove(i);
            }
            Larger::Reading(_) | Larger::Unfitted | Larger::No => i += 1,
        }
    }
    replaced
}

/// Whether the `larger` reading in report `i`'s place shows its own edges (where it lies apart
/// from the report) along edgels in the right image for [`super::ties::TIE_GAIN`] more of
/// their length than the report shows of its own there ([`super::ties::where_apart`]), the
/// other reports hiding and explaining what they do; true without a right image.
fn shown_in_the_right_image(
    models: &[MatcherModel],
    ev: &ImageEvidence,
    kept: &[Located],
    i: usize,
    larger: &Located,
) -> bool {
    let Some(right) = ev.right.as_deref() else { return true };
    let model_of = |name: &str| models.iter().find(|m| m.name == name);
    let (Some(own), Some(m)) = (model_of(&kept[i].model), model_of(&larger.model)) else { return false };
    let others = others_than(models, kept, i);
    let readings = ((own, &kept[i].cam_from_model), (m, &larger.cam_from_model));
    super::ties::where_apart_seen_from(readings, &others, (&right.right_from_cam, &right.ev))
        .is_some_and(|gain| gain > super::ties::TIE_GAIN)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::canny::{EdgeMap, Edgel};
    use crate::matcher::fixtures::model;
    use crate::matcher::verify::{Explained, drawn};
    use nalgebra::{Point2, Translation3};

    /// A U-channel holds an L-bracket (its bar and one arm along the bracket's), and nothing
    /// holds the channel; the pose puts the bracket's wireframe on the channel's.
    #[test]
    fn a_channel_holds_a_bracket_and_not_the_other_way() {
        let (bracket, channel) = (model("l_bracket"), model("u_channel"));
        let p = MatchParams::default();
        let poses = holding_poses(&bracket, &channel, &p);
        assert!(!poses.is_empty(), "the channel holds the bracket");
        let wireframe: Vec<Seg> =
            channel.lines.iter().take(channel.first_marking).map(|l| Seg::new(l.a, l.b)).collect();
        for bracket_from_channel in &poses {
            let channel_from_bracket = bracket_from_channel.inverse();
            let (support, _) = crate::matcher::support::support_at(&bracket, &channel_from_bracket, &wireframe, &p);
            assert!(support >= HOLDS * bracket.total_length, "{support} of {}", bracket.total_length);
            // The bracket's arm on one of the channel's: its box 5 mm along the channel's bar.
            let offset = channel_from_bracket.translation.vector;
            assert!((offset.norm() - 0.005).abs() < 0.001, "{offset:?}");
        }
        assert!(holding_poses(&channel, &bracket, &p).is_empty(), "a bracket is too small to hold a channel");
    }

    /// A U-channel lying on its side on the table, an L-bracket read in its corner (5 mm
    /// along, its bar end inside the channel's web), the camera that sees them, and the 3D
    /// lines round that corner alone: the channel's, left of its third arm.
    struct InTheCorner {
        bracket: MatcherModel,
        channel: MatcherModel,
        cam: mesh::PinholeCamera,
        channel_pose: Isometry3<f64>,
        bracket_pose: Isometry3<f64>,
        /// The height of the channel's top face (model frame, metres).
        top: f64,
        scene: Vec<Seg>,
    }

    impl InTheCorner {
        fn new() -> InTheCorner {
            let (bracket, channel) = (model("l_bracket"), model("u_channel"));
            let cam = crate::matcher::fixtures::camera_at(Point3::new(0.0, -0.6, 0.6));
            let place = |x: f64| {
                cam.cam_from_world() * Isometry3::from_parts(Translation3::new(x, 0.0, 0.0125), Default::default())
            };
            let (channel_pose, bracket_pose) = (place(0.0), place(-0.005));
            let top = channel.lines.iter().map(|l| l.a.z.max(l.b.z)).fold(f64::MIN, f64::max);
            let scene = channel.lines[..channel.first_marking]
                .iter()
                .filter(|l| l.a.x.max(l.b.x) < 0.024)
                .map(|l| l.transformed(&channel_pose))
                .collect();
            InTheCorner { bracket, channel, cam, channel_pose, bracket_pose, top, scene }
        }

        /// The channel's third arm's edges (x > 25 mm) in the image: those along the top of
        /// its end face (y = 25 mm) if `end_top`, else the others.
        fn arm(&self, end_top: bool) -> Vec<[Point2<f64>; 2]> {
            let on_end_top = |l: &Seg| l.a.y.min(l.b.y) > 0.0249 && l.a.z.min(l.b.z) > self.top - 1e-6;
            let (cam, pose) = (&self.cam, &self.channel_pose);
            self.channel.lines[..self.channel.first_marking]
                .iter()
                .filter(|l| l.a.x.min(l.b.x) > 0.0249 && on_end_top(l) == end_top)
                .filter_map(|l| Some([cam.project_cam(&(pose * l.a))?, cam.project_cam(&(pose * l.b))?]))
                .collect()
        }

        /// The bracket as reported, on little 3D evidence.
        fn reports(&self) -> [Located; 1] {
            [Located {
                support: 0.2 * self.bracket.total_length,
                support_fraction: 0.2,
                image_support: 0.6,
                ..crate::matcher::fixtures::report(&self.bracket, self.bracket_pose)
            }]
        }

        fn verdict(&self, ev: &ImageEvidence) -> Larger {
            let models = [self.bracket.clone(), self.channel.clone()];
            larger_reading(&models, (&self.scene, &MatchParams::default()), ev, (&self.reports(), MAX_SUPPORT), 0)
        }
    }

    /// Whether edgel `e` lies within `px` of one of `lines`.
    fn near(lines: &[[Point2<f64>; 2]], e: &Edgel, px: f64) -> bool {
        let q = Point2::new(f64::from(e.x), f64::from(e.y));
        lines.iter().any(|[a, b]| {
            let ab = b - a;
            let t = ((q - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
            (a + ab * t - q).norm() <= px
        })
    }

    type Keep<'a> = &'a dyn Fn(&Edgel) -> bool;

    /// An edge map of the edgels of each source that its test keeps.
    fn image(parts: &[(&EdgeMap, Keep)]) -> EdgeMap {
        let mut edges = EdgeMap::new(512, 512);
        for (source, keep) in parts {
            for (e, &pixel) in source.edgels.iter().zip(&source.pixel) {
                if keep(e) && edges.edgel_at(pixel as usize % 512, pixel as usize / 512).is_none() {
                    edges.push(pixel as usize, *e);
                }
            }
        }
        edges
    }

    /// A channel on the table whose third arm the image shows only along its top face's
    /// outline (its other edges as grey as the table beside them), read as the bracket in its
    /// other corner, on 3D lines round that corner alone: the image shows nothing of the
    /// bracket's bar end, and so the channel, faint as it is, is what lies there. Where the
    /// image shows the bracket's bar end (a bracket truly there, the same faint arm beside it),
    /// the bracket stands. Where the bar end is out of view, the faint arm is enough too.
    #[test]
    fn a_bracket_whose_bar_end_shows_nothing_gives_way_to_a_faint_channel() {
        let f = InTheCorner::new();
        let (bracket, channel, cam) = (&f.bracket, &f.channel, &f.cam);
        let (channel_pose, bracket_pose) = (f.channel_pose, f.bracket_pose);
        let (arm_top, arm_rest) = (f.arm(true), f.arm(false));
        let (channel_drawn, _) = drawn::model_edges(channel, &channel_pose, cam);
        let (bracket_drawn, _) = drawn::model_edges(bracket, &bracket_pose, cam);
        // The channel with its arm's edges off the top face gone.
        let on_channel = image(&[(&channel_drawn, &|e: &Edgel| !near(&arm_rest, e, 2.5))]);
        // A bracket truly there, and the same edges where the channel's arm's top would be.
        let all: Keep = &|_| true;
        let on_bracket = image(&[(&bracket_drawn, all), (&channel_drawn, &|e: &Edgel| near(&arm_top, e, 1.0))]);
        let nothing = Explained::of([], cam);
        // What each image shows beyond the other reading: the channel's arm, the bracket's end.
        let beyond = |ev: &ImageEvidence, (m, pose): (&MatcherModel, &Isometry3<f64>), other| {
            image_support_beyond((m, pose), other, ev, &[], &nothing, APART_PX, &|_| false)
        };
        let arm = |ev: &ImageEvidence| beyond(ev, (channel, &channel_pose), (bracket, &bracket_pose));
        let gives_way = |ev: &ImageEvidence| match f.verdict(ev) {
            Larger::Reading(l) => l.model == "u_channel",
            Larger::Unfitted => true,
            Larger::No | Larger::KeptFromView | Larger::Neither => false,
        };
        for edges in [&on_channel, &on_bracket] {
            let arm = arm(&ImageEvidence::new(cam, edges, Vec::new()));
            assert!(
                (SHOWN_BESIDE_NOTHING..SHOWN_BEYOND).contains(&arm.share) && arm.px >= MIN_BEYOND_PX,
                "the third arm shows faintly in both: {arm:?}"
            );
        }
        assert!(gives_way(&ImageEvidence::new(cam, &on_channel, Vec::new())), "the bracket stood on a faint channel");
        let ev = ImageEvidence::new(cam, &on_bracket, Vec::new());
        assert!(matches!(f.verdict(&ev), Larger::No), "a bracket whose bar end shows stands");
        // The channel's image cut off above the bracket's bar end: the end out of view, and
        // nothing to say for the bracket; the arm beyond it, faint, is enough for the channel.
        let end = cam.project_cam(&(bracket_pose * Point3::new(0.035, -0.01, f.top))).expect("in front");
        let rows = (end.y - 2.0).floor() as usize;
        let mut cut = EdgeMap::new(512, rows);
        for (e, &pixel) in on_channel.edgels.iter().zip(&on_channel.pixel) {
            if (pixel as usize) < rows * 512 {
                cut.push(pixel as usize, *e);
            }
        }
        let ev = ImageEvidence::new(cam, &cut, Vec::new());
        let (arm, end) = (arm(&ev), beyond(&ev, (bracket, &bracket_pose), (channel, &channel_pose)));
        assert!(end.px < MIN_OWN_PX && end.kept_from_view_px >= MIN_OWN_PX, "the bar end out of view: {end:?}");
        assert!(
            (SHOWN_BESIDE_HIDDEN..SHOWN_BEYOND).contains(&arm.share) && arm.px >= MIN_BEYOND_PX,
            "the third arm shows faintly: {arm:?}"
        );
        assert!(gives_way(&ev), "the bracket stood on a faint channel, its bar end out of view");
    }

    /// The channel of [`InTheCorner`] with nothing of its third arm in the image, read as the
    /// bracket in its corner: the image shows neither the bracket's bar end nor the arm, and
    /// the bracket is not made. Where stereo matched edgels on the table behind the arm's place
    /// (seen through it), no arm stands there, and the bracket does.
    #[test]
    fn a_bracket_that_a_channel_explains_as_well_is_not_made_unless_the_channel_is_seen_through() {
        let f = InTheCorner::new();
        let cam = &f.cam;
        let arm: Vec<_> = f.arm(true).into_iter().chain(f.arm(false)).collect();
        let (channel_drawn, _) = drawn::model_edges(&f.channel, &f.channel_pose, cam);
        let armless = image(&[(&channel_drawn, &|e: &Edgel| !near(&arm, e, 4.0))]);
        let ev = ImageEvidence::new(cam, &armless, Vec::new());
        assert!(matches!(f.verdict(&ev), Larger::Neither), "the bracket was made on what the channel shows as well");
        // Table markings seen through the arm's place: edgels along its middle, at the depth
        // of the table top behind it.
        let mut through = image(&[(&armless, &|_| true)]);
        let mut depths = Vec::new();
        for k in 0..30 {
            let y = -0.008 + 0.001 * f64::from(k);
            let Some(q) = cam.project_cam(&(f.channel_pose * Point3::new(0.0325, y, f.top))) else { continue };
            let (x, y) = (q.x.round() as usize, q.y.round() as usize);
            if through.edgel_at(x, y).is_some() {
                continue;
            }
            let ray = cam.ray_cam(x as f64, y as f64);
            let (origin, dir) = (cam.world_from_cam.translation.vector, cam.world_from_cam.rotation * ray);
            let along = -origin.z / dir.z;
            depths.push((through.edgels.len(), along * ray.z));
            let edgel = Edgel { x: x as f32, y: y as f32, orientation: 0.0, contrast: 30.0, sides: [80.0, 110.0] };
            through.push(y * 512 + x, edgel);
        }
        assert!(depths.len() >= 15, "{} edgels on the table", depths.len());
        let mut stereo = crate::matcher::depths::EdgelDepths::new(&through);
        for (i, z) in depths {
            stereo.insert(i, z, 0.004);
        }
        let ev = ImageEvidence::new(cam, &through, Vec::new()).with_depths(stereo);
        assert!(matches!(f.verdict(&ev), Larger::No), "the bracket stands where the channel is seen through");
    }

    /// The bracket read in the channel's corner, judged again once polished, seen by the
    /// verged pair: the left image shows the channel whole, and the right image the channel
    /// (the bracket gives way to it) or a bracket (the report stands: the left image alone
    /// does not make the channel).
    #[test]
    fn a_polished_bracket_gives_way_to_a_channel_only_where_the_right_image_shows_it_too() {
        let f = InTheCorner::new();
        let (left, right) = crate::matcher::fixtures::verged_pair();
        let left_from_f = left.cam_from_world() * f.cam.world_from_cam;
        let right_from_cam = right.cam_from_world() * left.world_from_cam;
        let (channel_pose, bracket_pose) = (left_from_f * f.channel_pose, left_from_f * f.bracket_pose);
        let scene: Vec<Seg> = f.scene.iter().map(|l| l.transformed(&left_from_f)).collect();
        let models = [f.bracket.clone(), f.channel.clone()];
        let (left_edges, _) = drawn::model_edges(&f.channel, &channel_pose, &left);
        let judged = |right_shows: (&MatcherModel, &Isometry3<f64>)| {
            let (right_edges, _) = drawn::model_edges(right_shows.0, &(right_from_cam * right_shows.1), &right);
            let right_ev = ImageEvidence::new(&right, &right_edges, Vec::new());
            let ev = ImageEvidence::new(&left, &left_edges, Vec::new())
                .with_right(super::super::verify::RightImage { ev: right_ev, right_from_cam });
            let mut kept = vec![Located {
                support: 0.2 * f.bracket.total_length,
                support_fraction: 0.2,
                image_support: 0.6,
                ..crate::matcher::fixtures::report(&f.bracket, bracket_pose)
            }];
            let replaced = settle_larger_once_polished(&models, (&scene, &MatchParams::default()), &ev, &mut kept);
            (kept[0].model.clone(), replaced)
        };
        assert_eq!(judged((&f.channel, &channel_pose)), ("u_channel".to_string(), vec![true]));
        assert_eq!(judged((&f.bracket, &bracket_pose)), ("l_bracket".to_string(), vec![false]));
    }

    /// A block's body (60 mm along x) holds a point deep inside it, and not one within
    /// [`ROOM_M`] of a face or outside it, wherever the block stands.
    #[test]
    fn a_body_holds_only_points_well_inside_it() {
        let block = model("block");
        let pose = Isometry3::new(Vector3::new(0.05, -0.02, 0.9), Vector3::new(0.3, -0.2, 1.1));
        let body = Body::new(&block, &pose);
        let (centre, _) = block.bounding_sphere();
        let at = |dx: f64| pose * (centre + Vector3::new(dx, 0.0, 0.0));
        assert!(body.holds_deep(&at(0.0)), "its centre");
        assert!(body.holds_deep(&at(0.025)), "5 mm inside its end");
        assert!(!body.holds_deep(&at(0.029)), "1 mm inside its end");
        assert!(!body.holds_deep(&at(0.035)), "5 mm beyond its end");
    }
}
