//! Two readings of different models on the same 3D evidence, told apart where they differ.
//!
//! Where a part is half hidden, a reading of another model can rest on the same few 3D lines
//! and run along more edgels in all, the part's true outline being the one cut short: a wedge
//! read on a block standing on end matched the same 0.135 m of 3D lines as the block on
//! realistic `dense.toml` tuning seed 52 and ran along edgels for 0.68 of its wireframe, the
//! block 0.59. What tells them apart is where they differ: there the wedge's slope showed no
//! edgel and the block's own edges 0.29 of theirs. The merge ([`super::merge`]) asks this of
//! the best report and each report of another model that fills the same space on as much 3D
//! evidence ([`TIE`]); the turn in stereo ([`super::polish`]) asks it of a report and its own
//! model turned, in both images ([`shown_where_apart`]).

use super::model::MatcherModel;
use super::occlusion::Solid;
use super::verify::{Explained, ImageEvidence, image_support_beyond};
use nalgebra::{Isometry3, Point3};

/// A report of another model ties with the best if it matches this share of the best's 3D
/// length or more (the ties seen on tuning seeds matched 0.98-1.01 of it).
pub(crate) const TIE: f64 = 0.95;
/// A rival takes the best's place if its own edges run along edgels for this much more of
/// their length than the best's own. Chosen on tuning seeds (`marvin eval locate`, realistic
/// `widgets.toml` 1-300 and `dense.toml` 1-60 through tuning seed 1's calibrations, ideal
/// `widgets.toml` 1-100 and `dense.toml` 1-60): of the 78 ties where the best was a right
/// report, the rival gained at most 0.14 (a U-channel round a right L-bracket, its third arm
/// crossed by other edges); of the 5 where it was a false one, 0.17-0.92. 0.15 would lie too
/// near the right ones'.
pub(crate) const TIE_GAIN: f64 = 0.2;
/// Readings closer than this (pixels) in the image are not told apart there.
const APART_PX: f64 = 3.0;
/// A rival is judged on at least this much of its own edges (pixels)...
const MIN_PX: f64 = 20.0;
/// ...and the best's own edges count only if there are this many pixels of them: a few say
/// nothing either way.
const MIN_OWN_PX: f64 = 10.0;

/// A model at a pose (`cam` frame).
pub(crate) type Reading<'m> = (&'m MatcherModel, &'m Isometry3<f64>);

/// How much more of its own edges (the wireframe more than [`APART_PX`] from the best's, none
/// that `hiding` hides or `explained` explains) the `rival` shows along edgels than the `best`
/// shows of its own, where that is more than [`TIE_GAIN`]; `None` otherwise.
pub(crate) fn gain_where_apart(
    readings: (Reading, Reading),
    ev: &ImageEvidence,
    hiding: &[&Solid],
    explained: &Explained,
) -> Option<f64> {
    where_apart(readings, ev, hiding, explained).filter(|gain| *gain > TIE_GAIN)
}

/// How much more of its own edges the `rival` shows along edgels than the `best` shows of its
/// own (as [`gain_where_apart`]), whatever it is; `None` where the rival has too little of its
/// own in view to tell ([`MIN_PX`]).
pub(crate) fn where_apart(
    (best, rival): (Reading, Reading),
    ev: &ImageEvidence,
    hiding: &[&Solid],
    explained: &Explained,
) -> Option<f64> {
    let nothing_taken = |_: &Point3<f64>| false;
    let own = image_support_beyond(best, rival, ev, hiding, explained, APART_PX, &nothing_taken);
    let theirs = image_support_beyond(rival, best, ev, hiding, explained, APART_PX, &nothing_taken);
    let own_share = if own.px >= MIN_OWN_PX { own.share } else { 0.0 };
    (theirs.px >= MIN_PX).then_some(theirs.share - own_share)
}

/// [`where_apart`] in the view of a camera whose frame is `cam_from_left` from the left
/// camera's, seeing `ev`: the readings and the `others` (the other reports, whose solids hide
/// and whose edges explain what they do there) given in the left camera's frame.
pub(crate) fn where_apart_seen_from(
    (best, rival): (Reading, Reading),
    others: &[Reading],
    (cam_from_left, ev): (&Isometry3<f64>, &ImageEvidence),
) -> Option<f64> {
    let moved: Vec<Isometry3<f64>> = others.iter().map(|(_, pose)| cam_from_left * *pose).collect();
    let placed = || others.iter().zip(&moved).map(|((m, _), pose)| (*m, pose));
    let solids: Vec<Solid> = placed().map(|(m, pose)| Solid::new(m, pose)).collect();
    let hiding: Vec<&Solid> = solids.iter().collect();
    let explained = Explained::of(placed(), ev.cam);
    let (a, b) = (cam_from_left * best.1, cam_from_left * rival.1);
    where_apart(((best.0, &a), (rival.0, &b)), ev, &hiding, &explained)
}

/// Whether the `turned` reading shows its own edges, where it and the `report` lie apart in
/// the image, along edgels for [`TIE_GAIN`] more of their
/// length than the report shows of its own, in each image where it has enough of them in view
/// ([`where_apart`]), and in one at least.
pub(crate) fn shown_where_apart(
    model: &MatcherModel,
    (report, turned): (&Isometry3<f64>, &Isometry3<f64>),
    (views, others): (&[super::image_fit::View], &[Vec<&Solid>]),
) -> bool {
    let gains: Vec<f64> = views
        .iter()
        .zip(others)
        .filter_map(|(v, hiding)| {
            let (a, b) = (v.cam_from_left * report, v.cam_from_left * turned);
            let explained = Explained::of(std::iter::empty(), v.ev.cam);
            where_apart(((model, &a), (model, &b)), v.ev, hiding, &explained)
        })
        .collect();
    !gains.is_empty() && gains.iter().all(|g| *g > TIE_GAIN)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::{camera_at, model};
    use crate::matcher::verify::drawn;
    use nalgebra::{Translation3, UnitQuaternion};

    /// A block on the table, and a wedge on the block's place (its bottom on the block's).
    fn block_and_wedge() -> (MatcherModel, MatcherModel, mesh::PinholeCamera, Isometry3<f64>, Isometry3<f64>) {
        let cam = camera_at(Point3::new(-0.1, -0.6894, 0.5785));
        let world_from_block = Isometry3::from_parts(
            Translation3::new(0.01, -0.02, 0.015),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.4),
        );
        // The wedge's bottom is 15 mm below its origin, the block's 15 mm below its centre.
        let block = cam.cam_from_world() * world_from_block;
        (model("block"), model("wedge"), cam, block, block)
    }

    /// The image shows a block: read as a wedge, the block's own edges (its top) show along
    /// edgels and the wedge's own (its slope) show none, so the block takes the wedge's place;
    /// read as the block, the wedge gains nothing.
    #[test]
    fn a_block_read_as_a_wedge_gives_way_to_the_block() {
        let (block, wedge, cam, block_pose, wedge_pose) = block_and_wedge();
        let (edges, lines) = drawn::model_edges(&block, &block_pose, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines);
        let explained = Explained::of(std::iter::empty(), &cam);
        let gain = gain_where_apart(((&wedge, &wedge_pose), (&block, &block_pose)), &ev, &[], &explained);
        assert!(gain.is_some_and(|g| g > 0.9), "the block shows its own edges: {gain:?}");
        let back = gain_where_apart(((&block, &block_pose), (&wedge, &wedge_pose)), &ev, &[], &explained);
        assert_eq!(back, None, "the wedge shows none of its own");
    }

    /// Where the image shows both readings' edges (as where another part's lie along the
    /// wedge's slope), neither shows its own better and the tie stands.
    #[test]
    fn a_tie_where_the_image_shows_both_stands() {
        let (block, wedge, cam, block_pose, wedge_pose) = block_and_wedge();
        let (mut edges, mut lines) = drawn::model_edges(&block, &block_pose, &cam);
        let (wedge_edges, wedge_lines) = drawn::model_edges(&wedge, &wedge_pose, &cam);
        for (e, &pixel) in wedge_edges.edgels.iter().zip(&wedge_edges.pixel) {
            if edges.edgel_at(pixel as usize % 512, pixel as usize / 512).is_none() {
                edges.push(pixel as usize, *e);
            }
        }
        lines.extend(wedge_lines);
        let ev = ImageEvidence::new(&cam, &edges, lines);
        let explained = Explained::of(std::iter::empty(), &cam);
        let gain = gain_where_apart(((&wedge, &wedge_pose), (&block, &block_pose)), &ev, &[], &explained);
        assert_eq!(gain, None);
    }
}
