//! Two reports that fill the same space: solids cannot, so where two located objects share
//! more than a sliver of their interiors one of them is not there.
//!
//! The merge ([`super::merge`]) refuses a report that shares more than [`MAX_SPACE_SHARED`] with
//! one kept before it; what the looks after it add, turn and polish may still overlap by less.
//! What the merge keeps at last is therefore sifted: of two reports sharing more than a
//! [`SLIVER`], the one with less evidence is dropped.
//!
//! On tuning seeds (`marvin eval locate`, realistic `widgets.toml` 1-300 and `dense.toml` 1-60
//! through tuning seed 1's calibrations, ideal `dense.toml` 1-60) two right reports shared at
//! most 0.006 of either's interior, and every pair sharing more held a false report: 11 of the
//! 32 false reports, sharing 0.005-0.185. Dropping the weaker of each pair sharing more than
//! a sliver (by the merge's own ranking, 3D length matched times the root of the share along
//! edgels) dropped 10 false reports
//! (realistic dense 14 -> 10, realistic widgets 101-300 7 -> 4, ideal dense 8 -> 5) and no
//! right one.

use super::model::{Located, MatcherModel};
use nalgebra::Isometry3;

/// Two objects cannot fill the same space: a report sharing more than this fraction of its own
/// interior, or of a kept object's, with that object is not admissible. Poses a millimetre off
/// share a sliver where solids touch; a second report of one object shares nearly all.
pub(crate) const MAX_SPACE_SHARED: f64 = 0.2;

/// Whether `a` (at `a_pose`) and `b` (at `b_pose`) share more than [`MAX_SPACE_SHARED`] of
/// either's interior: both cannot be there.
pub(crate) fn fill_the_same_space(
    a: &MatcherModel,
    a_pose: &Isometry3<f64>,
    b: &MatcherModel,
    b_pose: &Isometry3<f64>,
) -> bool {
    space_shared(a, a_pose, b, b_pose) > MAX_SPACE_SHARED || space_shared(b, b_pose, a, a_pose) > MAX_SPACE_SHARED
}

/// The fraction of `a`'s interior points (at `a_pose`) that lie inside `b` (at `b_pose`).
pub(crate) fn space_shared(
    a: &MatcherModel,
    a_pose: &Isometry3<f64>,
    b: &MatcherModel,
    b_pose: &Isometry3<f64>,
) -> f64 {
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

/// Two located objects sharing more than this fraction of either's interior cannot both be
/// there. The interior is a grid of points 4 mm apart whose nodes lie 2 mm in from the faces
/// ([`super::model::INTERIOR_STEP`]), so parts resting on each other with poses a millimetre
/// off share none; a few nodes are a sliver. On the tuning seeds above, 0.05 left two more
/// false reports (sharing 0.033 and 0.050) and dropped no right one either.
const SLIVER: f64 = 0.03;

/// Of every two reports in `kept` that share more than a sliver of space, the one with less
/// evidence (`evidence`) dropped: the reports stand strongest first, each unless it clashes
/// with one already standing. Those left keep their order.
pub(crate) fn drop_the_weaker(
    models: &[MatcherModel],
    kept: &mut Vec<Located>,
    evidence: impl Fn(&MatcherModel, &Located) -> f64,
) {
    let model_of = |l: &Located| models.iter().find(|m| m.name == l.model);
    let mut order: Vec<(usize, f64)> =
        kept.iter().enumerate().filter_map(|(i, l)| Some((i, evidence(model_of(l)?, l)))).collect();
    order.sort_by(|a, b| b.1.total_cmp(&a.1));
    let mut standing: Vec<usize> = Vec::new();
    for (i, _) in order {
        let Some(m) = model_of(&kept[i]) else { continue };
        let clashes = standing.iter().any(|&k| {
            model_of(&kept[k]).is_some_and(|o| {
                let (a, b) = (&kept[i].cam_from_model, &kept[k].cam_from_model);
                space_shared(m, a, o, b).max(space_shared(o, b, m, a)) > SLIVER
            })
        });
        if !clashes {
            standing.push(i);
        }
    }
    let mut stands = vec![false; kept.len()];
    for i in standing {
        stands[i] = true;
    }
    let mut stands = stands.into_iter();
    kept.retain(|_| stands.next().unwrap_or(false));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::model;
    use nalgebra::{Translation3, UnitQuaternion};

    /// A report of `name` at (`x`, `y`, `z`) metres in front of the camera, turned `yaw` about
    /// its own z, with `support` metres of 3D lines.
    fn report(name: &str, (x, y, z): (f64, f64, f64), yaw: f64, support: f64) -> Located {
        Located {
            model: name.to_string(),
            cam_from_model: Isometry3::from_parts(
                Translation3::new(x, y, z),
                UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
            ),
            support,
            support_fraction: 0.0,
            scene_lines: Vec::new(),
            image_support: 1.0,
            grasps: Vec::new(),
        }
    }

    /// Two blocks 60 x 40 x 30 mm side by side, a millimetre into each other, both stand; a
    /// third reading 20 mm into one of them, on less evidence, is dropped, whichever came first.
    #[test]
    fn of_two_reports_filling_the_same_space_the_weaker_is_dropped() {
        let models = [model("block")];
        let evidence = |_: &MatcherModel, l: &Located| l.support;
        let side_by_side = [report("block", (0.0, 0.0, 0.9), 0.0, 0.2), report("block", (0.059, 0.0, 0.9), 0.0, 0.1)];
        let mut kept = side_by_side.to_vec();
        drop_the_weaker(&models, &mut kept, evidence);
        assert_eq!(kept.len(), 2, "touching parts both stand");
        let mut kept = vec![report("block", (0.02, 0.01, 0.9), 0.5, 0.05)];
        kept.extend(side_by_side.iter().cloned());
        drop_the_weaker(&models, &mut kept, evidence);
        let left: Vec<f64> = kept.iter().map(|l| l.support).collect();
        assert_eq!(left, [0.2, 0.1], "the reading inside the first block is dropped, the others kept in order");
    }
}
