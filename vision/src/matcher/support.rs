//! The support a pose finds among the scene lines: the length of scene lines lying along the
//! model's lines where the pose puts them. The matcher ranks every hypothesis by it, so how
//! it is counted is most of the matcher's time: only the free lines whose midpoints lie near
//! the model are looked at, and of each only against the model lines its ends lie near (a
//! grid over the model, `model::LineGrid`).

use super::model::{LineGrid, MatchParams, MatcherModel, Seg};
use nalgebra::{Isometry3, Point3};

/// How a model line and a scene line (in one frame) agree: the length of the scene line lying along
/// the model segment (0 when they are not close and parallel).
pub(crate) fn overlap(model: &Seg, scene: &Seg, cos_tolerance: f64, p: &MatchParams) -> f64 {
    if model.dir.dot(&scene.dir).abs() < cos_tolerance {
        return 0.0;
    }
    let off = |x: &Point3<f64>| {
        let w = x - model.a;
        (w - model.dir * w.dot(&model.dir)).norm()
    };
    if off(&scene.a) > p.support_distance || off(&scene.b) > p.support_distance {
        return 0.0;
    }
    let (ta, tb) = ((scene.a - model.a).dot(&model.dir), (scene.b - model.a).dot(&model.dir));
    (ta.max(tb).min(model.len) - ta.min(tb).max(0.0)).max(0.0)
}

/// The support a given pose finds (matched scene length as a fraction of the wireframe, and
/// the model lines seen), for diagnosis and evaluation.
pub fn support_at(model: &MatcherModel, pose: &Isometry3<f64>, scene: &[Seg], p: &MatchParams) -> (f64, usize) {
    let (score, pairs) = support(model, pose, scene, &vec![true; scene.len()], p);
    (score / model.total_length, model_lines_of(&pairs).len())
}

/// The length of the scene lines of `pairs` (model line, scene line, overlap) that lies along
/// none of the model lines they match, counting only a line's excess of more than
/// [`OVERRUN_SLACK_M`] (a line's end found a little past a corner is no evidence).
pub(crate) fn overrun(pairs: &[(usize, usize, f64)], scene: &[Seg]) -> f64 {
    scene_lines_of(pairs)
        .into_iter()
        .map(|j| {
            let along: f64 = pairs.iter().filter(|x| x.1 == j).map(|x| x.2).sum();
            (scene[j].len - along).max(0.0)
        })
        .filter(|excess| *excess > OVERRUN_SLACK_M)
        .sum()
}

/// See [`overrun`], metres.
pub(crate) const OVERRUN_SLACK_M: f64 = 0.004;

/// The distinct model lines of (model line, scene line, overlap) correspondences, in order.
pub(crate) fn model_lines_of(pairs: &[(usize, usize, f64)]) -> Vec<usize> {
    distinct(pairs.iter().map(|&(i, ..)| i))
}

/// The distinct scene lines of (model line, scene line, overlap) correspondences, in order.
pub(crate) fn scene_lines_of(pairs: &[(usize, usize, f64)]) -> Vec<usize> {
    distinct(pairs.iter().map(|&(_, j, _)| j))
}

fn distinct(indices: impl Iterator<Item = usize>) -> Vec<usize> {
    let mut v: Vec<usize> = indices.collect();
    v.sort_unstable();
    v.dedup();
    v
}

/// The (model line, scene line, overlap length) correspondences a pose finds, for diagnosis.
pub fn correspondences_at(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    scene: &[Seg],
    p: &MatchParams,
) -> Vec<(usize, usize, f64)> {
    support(model, pose, scene, &vec![true; scene.len()], p).1
}

/// Support of a pose: per model line, the scene length along it (capped at its length), summed;
/// with the (model line, scene line, overlap) correspondences behind it.
pub(crate) fn support(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    scene: &[Seg],
    free: &[bool],
    p: &MatchParams,
) -> (f64, Vec<(usize, usize, f64)>) {
    support_among(model, pose, scene, &FreeLines::new(scene, free), p)
}

/// [`support`] among free lines laid out already (a refinement counts support several times
/// over the same free lines: laying them out each time was three fifths of its count).
pub(crate) fn support_among(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    scene: &[Seg],
    free_lines: &FreeLines,
    p: &MatchParams,
) -> (f64, Vec<(usize, usize, f64)>) {
    let mut pairs = Vec::new();
    for_each_overlap(model, pose, scene, free_lines, p, &mut NearLines::default(), |i, j, o| {
        if o > 0.0 {
            pairs.push((i, j, o));
        }
    });
    // By model line (each one's scene lines stay in order), as the sums below take them.
    pairs.sort_by_key(|&(i, ..)| i);
    let mut total = 0.0;
    for run in pairs.chunk_by(|x, y| x.0 == y.0) {
        total += run.iter().fold(0.0, |along, &(.., o)| along + o).min(model.lines[run[0].0].len);
    }
    (total, pairs)
}

/// Hands `each` the overlap (see [`overlap`]) of every free scene line near the model at
/// `pose` with each model line it may lie along (the others cannot support it), scene lines
/// in order.
pub(crate) fn for_each_overlap(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    scene: &[Seg],
    free: &FreeLines,
    p: &MatchParams,
    near: &mut NearLines,
    mut each: impl FnMut(usize, usize, f64),
) {
    let cos_tolerance = p.angle_tolerance.cos();
    let (centre, reach) = model.reach_at(pose, p);
    near.gather(free, &centre, reach);
    // Laid out on the first count; a count with another support distance takes every line.
    let grid = model.grid.get_or_init(|| LineGrid::new(model, p.support_distance));
    let grid_fits = grid.support_distance == p.support_distance;
    // Scene lines are taken into the model's frame, where the grid and the model lines are. (A
    // matrix turns a point in half the operations a quaternion does.)
    let inverse = pose.rotation.to_rotation_matrix().into_inner().transpose();
    let translation = pose.translation.vector;
    for &k in &near.index {
        let j = free.index[k];
        let sl = &scene[j];
        let dir = inverse * sl.dir;
        if !grid.may_run_along(&dir, cos_tolerance) {
            continue;
        }
        let in_model = Seg {
            a: Point3::from(inverse * (sl.a.coords - translation)),
            b: Point3::from(inverse * (sl.b.coords - translation)),
            dir,
            len: sl.len,
        };
        let ends = grid_fits.then_some((in_model.a, in_model.b));
        grid.each_line_along(ends.as_ref(), |i| each(i, j, overlap(&model.lines[i], &in_model, cos_tolerance, p)));
    }
}

/// The free scene lines laid out for the support count: their indices, and their midpoints in
/// single precision, coordinate by coordinate (the first test of each hypothesis, which runs
/// over them all, then runs several lines at a time).
pub(crate) struct FreeLines {
    index: Vec<usize>,
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
}

impl FreeLines {
    pub(crate) fn new(scene: &[Seg], free: &[bool]) -> FreeLines {
        let index: Vec<usize> = (0..scene.len()).filter(|&j| free[j]).collect();
        let mid: Vec<Point3<f64>> = index.iter().map(|&j| nalgebra::center(&scene[j].a, &scene[j].b)).collect();
        // Padded to whole chunks of lanes with midpoints at infinity, which lie near nothing.
        let coordinate = |k: usize| {
            let mut v: Vec<f32> = mid.iter().map(|m| m[k] as f32).collect();
            v.resize(index.len().next_multiple_of(LANES), f32::INFINITY);
            v
        };
        FreeLines { x: coordinate(0), y: coordinate(1), z: coordinate(2), index }
    }
}

/// Free lines' midpoints tested at a time in [`NearLines::gather`].
const LANES: usize = 8;

/// A support count's working space: the free lines near the pose, and per model line the
/// scene length along it.
#[derive(Default)]
pub(crate) struct NearLines {
    index: Vec<usize>,
    along: Vec<f64>,
}

impl NearLines {
    /// The free lines (indices into `free`) with their midpoint within `reach` of `centre`.
    fn gather(&mut self, free: &FreeLines, centre: &Point3<f64>, reach: f64) {
        let (cx, cy, cz, r2) = (centre.x as f32, centre.y as f32, centre.z as f32, (reach * reach) as f32);
        self.index.clear();
        // [`LANES`] lines at a time, in whole chunks and free of branches so that the tests
        // vectorise, into a bit per line; then the few that pass are picked out.
        let (xs, ys, zs) =
            (free.x.as_chunks::<LANES>().0, free.y.as_chunks::<LANES>().0, free.z.as_chunks::<LANES>().0);
        for (chunk, ((x, y), z)) in xs.iter().zip(ys).zip(zs).enumerate() {
            let mut d2 = [0f32; LANES];
            for i in 0..LANES {
                let (dx, dy, dz) = (x[i] - cx, y[i] - cy, z[i] - cz);
                d2[i] = dx * dx + dy * dy + dz * dz;
            }
            if d2.iter().all(|&d| d > r2) {
                continue;
            }
            let mut inside = d2.iter().enumerate().fold(0u32, |bits, (i, &d)| bits | (u32::from(d <= r2) << i));
            while inside != 0 {
                self.index.push(chunk * LANES + inside.trailing_zeros() as usize);
                inside &= inside - 1;
            }
        }
    }
}

/// The support of a pose alone, as [`support`] measures it, without the correspondences, if
/// it exceeds `floor`: the inner loop of hypothesis ranking, so the free lines come laid out
/// once per search and the working space is reused.
pub(crate) fn support_score(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    scene: &[Seg],
    free: &FreeLines,
    p: &MatchParams,
    floor: f64,
    near: &mut NearLines,
) -> Option<f64> {
    let mut along = std::mem::take(&mut near.along);
    along.clear();
    along.resize(model.lines.len(), 0.0);
    for_each_overlap(model, pose, scene, free, p, near, |i, _, o| along[i] += o);
    let total = model.longest_first.iter().fold(0.0, |total, &i| total + along[i].min(model.lines[i].len));
    near.along = along;
    (total > floor).then_some(total)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::Lcg;

    /// A scene line along a block's edge that runs 10 mm past its end overruns it by 10 mm; one
    /// found 3 mm long, or lying along two of its edges (none here), by nothing.
    #[test]
    fn a_line_running_past_an_edge_end_overruns_it() {
        let model = crate::matcher::fixtures::model("block");
        let pose = Isometry3::translation(0.0, 0.0, 0.8);
        let edge = model.lines[0].transformed(&pose);
        let past = |extra: f64| vec![Seg::new(edge.a, edge.b + edge.dir * extra)];
        for (extra, expect) in [(0.010, 0.010), (0.003, 0.0), (0.0, 0.0)] {
            let scene = past(extra);
            let pairs = correspondences_at(&model, &pose, &scene, &MatchParams::default());
            assert!(!pairs.is_empty(), "the line supports its edge");
            assert!((overrun(&pairs, &scene) - expect).abs() < 1e-9, "{extra} m past: {}", overrun(&pairs, &scene));
        }
    }

    /// The grid of lines near each cell never rules out a model line that a scene line lies
    /// along, nor do the model's directions: over random segments round and along every model,
    /// what they leave out has no overlap by the exhaustive test, and the cells do leave most
    /// lines out.
    #[test]
    fn the_line_grid_never_rules_out_a_line_a_scene_line_supports() {
        let lib = mesh::Library::load_default().unwrap();
        let p = MatchParams::default();
        let cos_tolerance = p.angle_tolerance.cos();
        let mut rng = Lcg(5);
        for name in ["widget", "l_bracket", "hex_prism", "u_channel"] {
            let model = MatcherModel::from_model(lib.get(name).unwrap());
            let grid = LineGrid::new(&model, p.support_distance);
            let (mut supported, mut candidates, mut tried, mut turned_away) = (0, 0, 0, 0);
            for n in 0..20_000 {
                // Half the segments run near a model line (a fragment of it, moved a little,
                // perhaps extended past its ends), half anywhere round the model.
                let scene = if n % 2 == 0 {
                    let l = &model.lines[n / 2 % model.lines.len()];
                    let (s0, s1) = (rng.next() * 1.4 - 0.2, rng.next() * 1.4 - 0.2);
                    let near = p.support_distance * 0.9;
                    Seg::new(l.a + (l.b - l.a) * s0 + rng.noise(near), l.a + (l.b - l.a) * s1 + rng.noise(near))
                } else {
                    let a = model.sphere.0 + rng.noise(model.sphere.1 + 0.03);
                    Seg::new(a, a + rng.noise(0.06))
                };
                let kept: Vec<usize> = grid.lines_along(Some(&(scene.a, scene.b))).collect();
                for (i, l) in model.lines.iter().enumerate() {
                    if overlap(l, &scene, cos_tolerance, &p) > 0.0 {
                        supported += 1;
                        assert!(kept.contains(&i), "{name}: line {i} ruled out though {scene:?} lies along it");
                        assert!(
                            grid.may_run_along(&scene.dir, cos_tolerance),
                            "{name}: {scene:?}'s direction ruled out"
                        );
                    }
                }
                (candidates, tried) = (candidates + kept.len(), tried + model.lines.len());
                turned_away += usize::from(n % 2 == 1 && !grid.may_run_along(&scene.dir, cos_tolerance));
            }
            assert!(supported > 1000, "{name}: only {supported} supporting segments drawn");
            assert!(candidates * 4 < tried, "{name}: the grid keeps {candidates} of {tried} lines");
            assert!(turned_away > 10_000 * 3 / 4, "{name}: only {turned_away} of 10000 lines turned away by direction");
        }
    }
}
