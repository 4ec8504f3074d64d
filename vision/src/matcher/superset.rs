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
/// [`HOLDS`] of `inner`'s (`inner_from_outer`), found once per pair of models (by name and
/// length) and kept.
pub(crate) fn holding_poses(inner: &MatcherModel, outer: &MatcherModel, p: &MatchParams) -> Vec<Isometry3<f64>> {
    type Key = (String, String, u64, u64);
    static KNOWN: OnceLock<Mutex<HashMap<Key, Vec<Isometry3<f64>>>>> = OnceLock::new();
    let key = (inner.name.clone(), outer.name.clone(), inner.total_length.to_bits(), outer.total_length.to_bits());
    let known = KNOWN.get_or_init(Default::default);
    if let Some(poses) = known.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return poses.clone();
    }
    let poses = if outer.total_length < LARGER_BY * inner.total_length {
        Vec::new()
    } else {
        // The smaller model sought among the larger one's lines: where it is found, the larger
        // one holds it.
        let wireframe: Vec<Seg> = outer.lines.iter().take(outer.first_marking).map(|l| Seg::new(l.a, l.b)).collect();
        let bare = MatchParams { table: None, ..*p };
        let found = super::search::locate(inner, &wireframe, &bare, None);
        found
            .into_iter()
            .filter(|l| l.support >= HOLDS * inner.total_length)
            .map(|l| l.cam_from_model.inverse())
            .collect()
    };
    known.lock().unwrap_or_else(|e| e.into_inner()).insert(key, poses.clone());
    poses
}

/// What to make of report `i` (of `kept`, the others solids that may hide it and edges that
/// explain edgels) where a larger model holds it: the image shows the larger model's edges
/// beyond the report's (along edgels for [`SHOWN_BEYOND`] of [`MIN_BEYOND_PX`] or more, hidden
/// parts and the others' edges left out) at some holding pose. Only reports on little 3D evidence (`max_support` of their model's length) are
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
    let others: Vec<(&MatcherModel, &Isometry3<f64>)> = kept
        .iter()
        .enumerate()
        .filter(|(k, _)| *k != i)
        .filter_map(|(_, l)| models.iter().find(|m| m.name == l.model).map(|m| (m, &l.cam_from_model)))
        .collect();
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
    let shown: Vec<(&MatcherModel, Isometry3<f64>)> = beyond
        .iter()
        .filter(|(_, _, b)| b.share >= SHOWN_BEYOND && b.px >= MIN_BEYOND_PX)
        .map(|(m, pose, _)| (*m, *pose))
        .collect();
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
            Larger::Unfitted | Larger::KeptFromView => {
                kept.remove(i);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::model;

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
