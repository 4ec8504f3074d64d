//! Characteristic views and their pairwise tables: for each of the model's six axis
//! directions, the lines a viewer there can see, and the focus pairs among them (each focus
//! line, the view's longest in each direction by turns, in the manner of Bolles, with its
//! feature group) with their relations, as in Grimson & Lozano-Perez's tables. Pairs that the
//! model's symmetry makes equivalent are tabled once.

use super::model::{FocusPair, MatchParams, MatcherModel, Seg, closest_params, line_angle, separation};
use super::pose_fit::{DirectionPair, PointOnLine, pose_from_lines};
use nalgebra::Vector3;

/// The focus pairs among `lines`: each focus line (the longest of them) with its feature group
/// (the lines not near-parallel to it). A pair that the model's own symmetry maps onto a pair
/// already tabled (in `tabled` or among the new ones), or the same two lines the other way
/// round, is left out: the hypotheses it would give are the same poses (up to the symmetry,
/// which is as correct), and each costs a support evaluation.
pub(crate) fn focus_pairs_among(
    model: &MatcherModel,
    lines: &[usize],
    p: &MatchParams,
    tabled: &[FocusPair],
) -> Vec<FocusPair> {
    let mut out: Vec<FocusPair> = Vec::new();
    for i in focus_lines(model, lines, p.focus_lines) {
        for &k in lines {
            let (li, lk) = (&model.lines[i], &model.lines[k]);
            let angle = line_angle(&li.dir, &lk.dir);
            let seen = |f: &FocusPair| (f.focus == k && f.partner == i) || (f.focus == i && f.partner == k);
            if k == i || angle <= 0.35 || out.iter().chain(tabled).any(seen) {
                continue;
            }
            let (at_focus, at_partner) = closest_params(&li.a, &li.dir, &lk.a, &lk.dir);
            let separation = separation(&li.a, &li.dir, &lk.a, &lk.dir);
            let pair = FocusPair { focus: i, partner: k, angle, separation, at_focus, at_partner };
            if !out.iter().chain(tabled).any(|f| symmetric_images(model, f, &pair)) {
                out.push(pair);
            }
        }
    }
    out
}

/// The focus lines among `lines`: the longest, taken by turns from each direction the lines
/// run in (longest direction first), so that a view's focus lines do not all run one way.
/// Stereo recovers no edge near the rasters' direction; when the focus lines all ran along
/// it (the L-bracket's 70 and 55 mm edges are parallel), the object could not be seeded at all.
pub(crate) fn focus_lines(model: &MatcherModel, lines: &[usize], count: usize) -> Vec<usize> {
    let mut order = lines.to_vec();
    order.sort_by(|&a, &b| model.lines[b].len.total_cmp(&model.lines[a].len));
    // Group the lines by direction, each group longest first; the groups in order of their longest.
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for i in order {
        let d = &model.lines[i].dir;
        match groups.iter_mut().find(|g| line_angle(&model.lines[g[0]].dir, d) < 0.35) {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    let mut out = Vec::new();
    for round in 0.. {
        let before = out.len();
        out.extend(groups.iter().filter_map(|g| g.get(round)).take(count - out.len()));
        if out.len() == count || out.len() == before {
            break;
        }
    }
    out
}

/// Characteristic views: for each of the model's six axis directions, the lines on faces that
/// a viewer looking from near there can see, with the focus pairs among them (pairs an earlier
/// view tabled are not tabled again). A subordinate matcher searches for each view.
pub(crate) fn characteristic_views(model: &MatcherModel, p: &MatchParams) -> Vec<Vec<FocusPair>> {
    let mut tabled: Vec<FocusPair> = Vec::new();
    let mut views = Vec::new();
    for axis in 0..3 {
        for sign in [1.0, -1.0] {
            let towards = Vector3::ith(axis, sign);
            let lines: Vec<usize> = (0..model.lines.len())
                .filter(|&i| model.faces[i].is_empty() || model.faces[i].iter().any(|n| n.dot(&towards) > VIEW_FACING))
                .collect();
            let mut pairs = focus_pairs_among(model, &lines, p, &tabled);
            tabled.extend_from_slice(&pairs);
            // By separation, so that a scene pair finds the focus pairs it may match by bisection.
            pairs.sort_by(|a, b| a.separation.total_cmp(&b.separation));
            views.push(pairs);
        }
    }
    views
}

/// A face belongs to a view when its normal is within about 96 deg of the view direction: a
/// viewer above an object lying flat sees its top and, obliquely, its sides, and the pairs that
/// seed hypotheses often join a top edge to a side edge.
pub(crate) const VIEW_FACING: f64 = -0.1;

/// Whether a rigid motion that takes pair `b`'s lines onto pair `a`'s (ends to ends) maps the
/// whole wireframe onto itself.
pub(crate) fn symmetric_images(model: &MatcherModel, a: &FocusPair, b: &FocusPair) -> bool {
    const EXACT: f64 = 1e-6;
    let congruent = (a.angle - b.angle).abs() < EXACT
        && (a.separation - b.separation).abs() < EXACT
        && (model.lines[a.focus].len - model.lines[b.focus].len).abs() < EXACT
        && (model.lines[a.partner].len - model.lines[b.partner].len).abs() < EXACT;
    if !congruent {
        return false;
    }
    // Either end of each line may map onto either end of its image.
    let ends = |s: &Seg| [(s.a, s.b), (s.b, s.a)];
    let (af, ap) = (&model.lines[a.focus], &model.lines[a.partner]);
    for (fa, fb) in ends(&model.lines[b.focus]) {
        for (pa, pb) in ends(&model.lines[b.partner]) {
            let from = Seg::new(fa, fb);
            let dirs = [
                DirectionPair { model: from.dir, scene: af.dir, weight: 1.0 },
                DirectionPair { model: Seg::new(pa, pb).dir, scene: ap.dir, weight: 1.0 },
            ];
            let points = [
                PointOnLine { scene: af.a, model_point: fa, model_direction: from.dir, weight: 1.0 },
                PointOnLine { scene: ap.a, model_point: pa, model_direction: Seg::new(pa, pb).dir, weight: 1.0 },
                PointOnLine { scene: af.b, model_point: fa, model_direction: from.dir, weight: 1.0 },
                PointOnLine { scene: ap.b, model_point: pa, model_direction: Seg::new(pa, pb).dir, weight: 1.0 },
            ];
            let Some(t) = pose_from_lines(&dirs, &points) else { continue };
            let maps_onto_itself = model.lines.iter().all(|l| {
                let (ta, tb) = (t * l.a, t * l.b);
                model.lines.iter().any(|m| {
                    ((m.a - ta).norm() < 1e-5 && (m.b - tb).norm() < 1e-5)
                        || ((m.a - tb).norm() < 1e-5 && (m.b - ta).norm() < 1e-5)
                })
            });
            if maps_onto_itself {
                return true;
            }
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The L-bracket's four longest edges all run along its length; its focus lines must not,
    /// or an L-bracket whose length lies along the rasters could not be seeded.
    #[test]
    fn focus_lines_run_in_every_direction_the_model_has() {
        let model = crate::matcher::fixtures::model("l_bracket");
        let all: Vec<usize> = (0..model.lines.len()).collect();
        let focus = focus_lines(&model, &all, 4);
        assert_eq!(focus.len(), 4);
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            assert!(
                focus.iter().any(|&i| line_angle(&model.lines[i].dir, &axis) < 0.1),
                "no focus line along {axis:?}: {focus:?}"
            );
        }
        // The longest line of each direction comes first: the 70 mm edge, then the 50 mm one.
        assert_eq!(model.lines[focus[0]].len, model.lines.iter().map(|l| l.len).fold(0.0, f64::max));
        assert!((model.lines[focus[1]].len - 0.05).abs() < 1e-9);
    }
}
