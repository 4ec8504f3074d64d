//! Hypotheses: a scene pair congruent with a focus pair, within tolerances that let fragments
//! and partly seen lines qualify, gives a pose by least squares; each is scored by the support
//! it finds, and only those that can make a search's best are kept. One subordinate matcher per
//! characteristic view, in parallel; a later instance rescores the same hypotheses.

use super::model::{FocusPair, MatchParams, MatcherModel, Seg, closest_params, line_angle, separation};
use super::pose_fit::{PointOnLine, rotation_from_two_directions, translation_from_points};
use super::support::{FreeLines, NearLines, support_score};
use super::table::{hopelessly_sunk, nearly_flat};
use nalgebra::{Isometry3, Point3, Vector3};

/// A hypothesis: its support and its pose.
pub(crate) type Scored = (f64, Isometry3<f64>);

/// Whether a fragment of length `frag` whose closest approach to its partner falls at `t` from
/// its start can lie, running the same way, on a model line of length `len` whose closest
/// approach falls at `m`: the fragment is some stretch of the model line.
pub(crate) fn fits_along(t: f64, frag: f64, m: f64, len: f64, tol: f64) -> bool {
    frag <= len + tol && t >= m - (len - frag) - tol && t <= m + tol
}

/// The hypotheses that congruent scene pairs (of `pairs`, all of free lines) give and that find
/// at least the support a located object needs (`min_support_fraction` of the wireframe) and
/// make the search's best so far (see [`Seen`]), with that support; and apart, those short of
/// it that put the part flat on the table (see [`Seen::flat`]).
pub(crate) fn hypotheses(
    model: &MatcherModel,
    scene: &[Seg],
    pairs: &ScenePairs,
    views: &[Vec<FocusPair>],
    p: &MatchParams,
) -> (Vec<Scored>, Vec<Scored>) {
    use rayon::prelude::*;
    let free_lines = FreeLines::new(scene, &vec![true; scene.len()]);
    // One subordinate matcher per characteristic view, in parallel.
    let per_view: Vec<_> = views
        .par_iter()
        .map(|focus| {
            let mut seen =
                Seen::new(model, p.min_support_fraction * model.total_length, RECORDED_PER_KEPT * p.hypotheses);
            let focus = FocusTable::new(focus, p);
            for_each_hypothesis(model, scene, (pairs, &free_lines), &focus, p, &mut seen);
            (seen.all, seen.flat.all)
        })
        .collect();
    let (all, flat): (Vec<_>, Vec<_>) = per_view.into_iter().unzip();
    (all.concat(), flat.concat())
}

/// The hypotheses of an earlier search with their support among the lines still free, those
/// that still find enough. A later search for another instance would find no others: its
/// scene pairs are among the earlier ones, giving the same poses, and support only shrinks as
/// lines are claimed. (Searching again took half the matcher's time.)
pub(crate) fn rescored(
    model: &MatcherModel,
    scene: &[Seg],
    free: &[bool],
    earlier: &[(f64, Isometry3<f64>)],
    p: &MatchParams,
) -> Vec<(f64, Isometry3<f64>)> {
    let free_lines = FreeLines::new(scene, free);
    let floor = p.min_support_fraction * model.total_length;
    let mut near = NearLines::default();
    earlier
        .iter()
        .filter_map(|(_, pose)| {
            support_score(model, pose, scene, &free_lines, p, floor, &mut near).map(|score| (score, *pose))
        })
        .collect()
}

/// The hypotheses of a search that find support above `floor` and, once `recorded` have at
/// the same place, above the least of the best `recorded` there so far (a hypothesis that
/// cannot make those is neither this search's best there nor, once lines are claimed, a later
/// one's).
///
/// The best are kept per place, not over the whole scene: an object's own hypotheses are many
/// and well supported, and with one floor for the scene they set it above every hypothesis of a
/// second instance of the model, or of a part that other objects' lines drew hypotheses away
/// from; once the first was located and its lines claimed, nothing was left to find the second
/// with (dense seed 32: a widget in plain view on 15 lines, support 0.56, never hypothesised).
pub(crate) struct Seen {
    pub(crate) floor: f64,
    pub(crate) all: Vec<(f64, Isometry3<f64>)>,
    /// The best scores so far at each place, least on top.
    best: Places,
    /// How many of the best at a place set its floor.
    pub(crate) recorded: usize,
    /// The middle of the model's wireframe (`model` frame), whose place a pose gives.
    middle: Point3<f64>,
    /// Hypotheses short of `floor` that put the part flat on the table, with at least
    /// [`FLAT_MIN_SUPPORT`] of its wireframe's length: the table look's starts
    /// ([`super::table_look`]), the best [`FLAT_PER_PLACE`] at each place.
    pub(crate) flat: Flat,
}

/// The best scores so far at each place, least on top. (Hashed with foldhash: the standard
/// SipHash took a twentieth of the hypotheses' time, looking up a place for each of them.)
type Places = std::collections::HashMap<
    [i32; 3],
    std::collections::BinaryHeap<std::cmp::Reverse<Score>>,
    foldhash::fast::FixedState,
>;

/// See [`Seen::flat`].
#[derive(Default)]
pub(crate) struct Flat {
    pub(crate) all: Vec<(f64, Isometry3<f64>)>,
    best: Places,
}

/// A hypothesis lying flat on the table is kept for the table look with this share of the
/// wireframe's length along 3D lines (the first look asks `min_support_fraction`).
pub(crate) const FLAT_MIN_SUPPORT: f64 = 0.06;

/// Flat hypotheses kept per place (see [`PLACE_M`]).
const FLAT_PER_PLACE: usize = 4;

/// Hypotheses whose support sets the floor of a search at a place, per hypothesis kept for
/// verification (`MatchParams::hypotheses`). With one floor for the whole scene, 60 for the 12
/// kept found slightly more objects than keeping every hypothesis over the minimum support,
/// with 5% less work, and 30 found fewer. Per place, 36 and 60 found the same objects on the
/// tuning seeds (see [`PLACE_M`]), and so did keeping every hypothesis.
pub(crate) const RECORDED_PER_KEPT: usize = 3;

/// The side of a place (metres, in `cam`): a cube of the size of the parts. Hypotheses of one
/// object fall in one or two places, those of objects apart in others. On tuning seeds
/// (`marvin eval locate`, `widgets.toml` 1-500, `dense.toml` and `side_light.toml` 1-200)
/// 0.025, 0.05 and 0.1 m found the same objects.
const PLACE_M: f64 = 0.05;

/// A support score, ordered.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Score(f64);

impl Eq for Score {}

impl PartialOrd for Score {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Score {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

impl Seen {
    fn new(model: &MatcherModel, floor: f64, recorded: usize) -> Seen {
        let midpoints = model.lines.iter().map(|l| (l.a.coords + l.b.coords) * 0.5);
        let middle = Point3::from(midpoints.sum::<Vector3<f64>>() / model.lines.len().max(1) as f64);
        Seen { floor, all: Vec::new(), best: Default::default(), recorded, middle, flat: Flat::default() }
    }

    /// The place (a cell of [`PLACE_M`]) where `pose` puts the model.
    fn place(&self, pose: &Isometry3<f64>) -> [i32; 3] {
        let at = pose * self.middle;
        // As `floor() as i32` does, saturating.
        [at.x, at.y, at.z].map(|v| crate::image::floor_int(v / PLACE_M).clamp(i32::MIN.into(), i32::MAX.into()) as i32)
    }

    /// The support a hypothesis at `pose` must exceed to be recorded.
    fn floor(&self, pose: &Isometry3<f64>) -> f64 {
        floor_at(&self.best, self.place(pose), self.recorded, self.floor)
    }

    /// The support a hypothesis at `pose`, flat on the table, must exceed to be kept for the
    /// table look.
    fn flat_floor(&self, model: &MatcherModel, pose: &Isometry3<f64>) -> f64 {
        floor_at(&self.flat.best, self.place(pose), FLAT_PER_PLACE, FLAT_MIN_SUPPORT * model.total_length)
    }

    fn record(&mut self, score: f64, pose: Isometry3<f64>) {
        self.all.push((score, pose));
        let place = self.place(&pose);
        keep_best(&mut self.best, place, self.recorded, score);
    }

    fn record_flat(&mut self, score: f64, pose: Isometry3<f64>) {
        self.flat.all.push((score, pose));
        let place = self.place(&pose);
        keep_best(&mut self.flat.best, place, FLAT_PER_PLACE, score);
    }
}

/// The support a hypothesis at `place` must exceed: `floor`, or once `recorded` are kept
/// there, the least of them.
fn floor_at(best: &Places, place: [i32; 3], recorded: usize, floor: f64) -> f64 {
    match best.get(&place).and_then(|best| Some((best.len(), best.peek()?.0.0))) {
        Some((kept, least)) if kept == recorded => floor.max(least),
        _ => floor,
    }
}

fn keep_best(best: &mut Places, place: [i32; 3], recorded: usize, score: f64) {
    let best = best.entry(place).or_default();
    best.push(std::cmp::Reverse(Score(score)));
    if best.len() > recorded {
        best.pop();
    }
}

/// Two free scene lines that could seed a hypothesis, with their relations.
pub(crate) struct ScenePair {
    pub(crate) j: usize,
    pub(crate) l: usize,
    pub(crate) angle: f64,
    pub(crate) separation: f64,
    /// Where the closest approach falls along each, from its start.
    pub(crate) at_j: f64,
    pub(crate) at_l: f64,
    /// Its cell in a [`FocusTable`] laid out with the same tolerances.
    cell: [u32; 2],
}

/// The scene's seed pairs, with the same pairs by cell for the views to take theirs from.
pub(crate) struct ScenePairs {
    pairs: Vec<ScenePair>,
    by_cell: PairsByCell,
}

impl std::ops::Deref for ScenePairs {
    type Target = [ScenePair];
    fn deref(&self) -> &[ScenePair] {
        &self.pairs
    }
}

/// Every ordered pair of scene lines long enough to seed and far enough from parallel.
pub(crate) fn scene_pairs(scene: &[Seg], p: &MatchParams) -> ScenePairs {
    let pairs = seed_pairs(scene, p);
    ScenePairs { by_cell: PairsByCell::new(&pairs), pairs }
}

/// See [`scene_pairs`].
fn seed_pairs(scene: &[Seg], p: &MatchParams) -> Vec<ScenePair> {
    let seeds: Vec<usize> = (0..scene.len()).filter(|&j| scene[j].len >= p.min_seed_length).collect();
    // Each unordered pair's relations worked out once (every search waits on them): swapped,
    // the angle and separation are the same and the closest approach's places trade over, bit
    // for bit (each product and sum is taken again with its terms swapped or negated).
    let n = seeds.len();
    let mut relations = vec![None; n * n];
    for a in 0..n {
        for b in a + 1..n {
            let (sj, sl) = (&scene[seeds[a]], &scene[seeds[b]]);
            let angle = line_angle(&sj.dir, &sl.dir);
            if angle < 0.3 {
                continue;
            }
            let separation = separation(&sj.a, &sj.dir, &sl.a, &sl.dir);
            let (at_a, at_b) = closest_params(&sj.a, &sj.dir, &sl.a, &sl.dir);
            relations[a * n + b] = Some((angle, separation, at_a, at_b));
            relations[b * n + a] = Some((angle, separation, at_b, at_a));
        }
    }
    let mut out = Vec::with_capacity(relations.iter().flatten().count());
    for (a, &j) in seeds.iter().enumerate() {
        for (b, &l) in seeds.iter().enumerate() {
            let Some((angle, separation, at_j, at_l)) = relations[a * n + b] else { continue };
            let cell = [cell_of(separation, p.separation_tolerance), cell_of(angle, p.angle_tolerance)];
            out.push(ScenePair { j, l, angle, separation, at_j, at_l, cell });
        }
    }
    out
}

/// The scene pairs (indices into the scene's pairs, in order) by their cell, laid out as a
/// [`FocusTable`] of as many cells as they reach lays them out: a view's subordinate matcher
/// takes those of the cells where it has focus pairs.
pub(crate) struct PairsByCell {
    /// Cells across separation and across angle.
    cells: [u32; 2],
    /// Where each cell's pairs begin in `listed` (and end where the next cell's begin).
    starts: Vec<u32>,
    listed: Vec<u32>,
}

impl PairsByCell {
    pub(crate) fn new(pairs: &[ScenePair]) -> PairsByCell {
        let reach = |k: usize| pairs.iter().map(|sp| sp.cell[k] + 1).max().unwrap_or(0);
        let cells = [reach(0), reach(1)];
        let index = |sp: &ScenePair| (sp.cell[0] * cells[1] + sp.cell[1]) as usize;
        let (starts, listed) = laid_out_by_cell(
            (cells[0] * cells[1]) as usize,
            pairs.iter().enumerate().map(|(i, sp)| (index(sp), i as u32)).collect(),
        );
        PairsByCell { cells, starts, listed }
    }

    /// The pairs of cell (`separation`, `angle`): none beyond the cells they reach.
    fn of(&self, [separation, angle]: [u32; 2]) -> &[u32] {
        if separation >= self.cells[0] || angle >= self.cells[1] {
            return &[];
        }
        let cell = (separation * self.cells[1] + angle) as usize;
        &self.listed[self.starts[cell] as usize..self.starts[cell + 1] as usize]
    }
}

/// The scene pairs that fall in cells of `focus` holding a focus pair, in order (the floors
/// of the places depend on it). A view's cells are mostly empty: each pair was once looked at
/// in every view, and that was a twentieth of the matcher's instructions.
fn pairs_in_view(pairs: &ScenePairs, focus: &FocusTable) -> impl Iterator<Item = usize> {
    let mut chosen = vec![0u64; pairs.len().div_ceil(64)];
    for cell in focus.held_cells() {
        for &i in pairs.by_cell.of(cell) {
            chosen[i as usize / 64] |= 1 << (i % 64);
        }
    }
    chosen.into_iter().enumerate().flat_map(|(w, mut word)| {
        std::iter::from_fn(move || {
            (word != 0).then(|| {
                let bit = word.trailing_zeros() as usize;
                word &= word - 1;
                w * 64 + bit
            })
        })
    })
}

/// Hands `sink` each hypothesis from a scene pair congruent with a focus pair, with its support
/// (those that cannot beat the sink's floor are left unscored and unseen).
pub(crate) fn for_each_hypothesis(
    model: &MatcherModel,
    scene: &[Seg],
    (pairs, free_lines): (&ScenePairs, &FreeLines),
    focus: &FocusTable,
    p: &MatchParams,
    sink: &mut Seen,
) {
    let mut near = NearLines::default();
    let tolerance = p.separation_tolerance;
    for sp in pairs_in_view(pairs, focus).map(|i| &pairs[i]) {
        let (sj, sl) = (&scene[sp.j], &scene[sp.l]);
        let (tj, tl) = (sp.at_j, sp.at_l);
        {
            for f in focus.near(sp) {
                if f.separation < sp.separation - tolerance || f.separation > sp.separation + tolerance {
                    continue;
                }
                if (sp.angle - f.angle).abs() > p.angle_tolerance {
                    continue;
                }
                let (mi, mk) = (&model.lines[f.focus], &model.lines[f.partner]);
                // Each fragment must fit along its model line with the closest approach where the
                // model has it (with slack for the ends stereo loses); that fixes which way round
                // each scene line runs, and the model pair's cosine sign must agree.
                let slack = FIT_SLACK * p.support_distance;
                let cos = mi.dir.dot(&mk.dir);
                let fits_j = |sign_j: f64| {
                    let tj_from_start = if sign_j > 0.0 { tj } else { sj.len - tj };
                    fits_along(tj_from_start, sj.len, f.at_focus, mi.len, slack)
                };
                let ways = [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)];
                let (fits_forwards, fits_backwards) = (fits_j(1.0), fits_j(-1.0));
                for (sign_j, sign_l) in ways {
                    if !(if sign_j > 0.0 { fits_forwards } else { fits_backwards }) {
                        continue;
                    }
                    let vj = sj.dir * sign_j;
                    // The cosine's sign must agree, unless the lines are too near perpendicular
                    // for it to say anything: then both ways round are tried (taking the noise's
                    // word for it lost one of a rectangle's two readings, and with it many
                    // objects, which came out turned over).
                    let scene_cos = vj.dot(&sl.dir) * sign_l;
                    if cos.abs() > PERPENDICULAR_COS && (scene_cos >= 0.0) != (cos >= 0.0) {
                        continue;
                    }
                    let tl_from_start = if sign_l > 0.0 { tl } else { sl.len - tl };
                    if !fits_along(tl_from_start, sl.len, f.at_partner, mk.len, slack) {
                        continue;
                    }
                    let vl = sl.dir * sign_l;
                    let Some(rotation) = rotation_from_two_directions([mi.dir, mk.dir], [vj, vl]) else { continue };
                    // A reading that puts a seed line on the part's far side is no reading:
                    // each scene line, seen, must lie along an edge the camera may see (the
                    // line of sight to its middle, carried into the model's frame).
                    let sight = |s: &Seg| rotation.inverse_transform_vector(&-nalgebra::center(&s.a, &s.b).coords);
                    if !model.may_be_seen_along(f.focus, &sight(sj)) || !model.may_be_seen_along(f.partner, &sight(sl))
                    {
                        continue;
                    }
                    let on = |x: Point3<f64>, m: &Seg| PointOnLine {
                        scene: x,
                        model_point: m.a,
                        model_direction: m.dir,
                        weight: 1.0,
                    };
                    let points = [on(sj.a, mi), on(sj.b, mi), on(sl.a, mk), on(sl.b, mk)];
                    let Some(t) = translation_from_points(&rotation, &points) else { continue };
                    let pose = Isometry3::from_parts(t.into(), rotation);
                    // Nor is one with the part deep in the table: neither is worth counting
                    // support for.
                    if hopelessly_sunk(p.table.as_ref(), model, &pose) {
                        continue;
                    }
                    // Counted in full whatever the floor (the count stops at no floor), so the
                    // flat test waits for a score that needs it.
                    let Some(score) = support_score(model, &pose, scene, free_lines, p, f64::MIN, &mut near) else {
                        continue;
                    };
                    if score > sink.floor(&pose) {
                        sink.record(score, pose);
                    } else if score <= sink.floor
                        && score > FLAT_MIN_SUPPORT * model.total_length
                        && p.table.as_ref().is_some_and(|t| nearly_flat(t, model, &pose))
                        && score > sink.flat_floor(model, &pose)
                    {
                        // Short of the first look's floor, a pose flat on the table is still
                        // worth a table look. (Between that floor and a busy place's lie the
                        // variants of better-supported readings: the first look's matter.)
                        sink.record_flat(score, pose);
                    }
                }
            }
        }
    }
}

/// A view's focus pairs laid out by separation and angle in cells half a tolerance wide, so
/// that a scene pair looks only at those of its cell: the focus pairs within the tolerances of
/// some separation and angle in it. Each scene pair sought its focus pairs by a binary search
/// over separation, then tested their angles, and seven in ten of those it found failed the
/// angle (`marvin bench vision`'s scene): the search and the loop round it were a third of the
/// hypotheses' time.
pub(crate) struct FocusTable<'f> {
    focus: &'f [FocusPair],
    /// Where each cell's focus pairs (separation cell by angle cell, row-major) begin in
    /// `listed`, and end where the next cell's begin.
    starts: Vec<u32>,
    /// Each cell's focus pairs (indices into `focus`), in `focus`'s order.
    listed: Vec<u16>,
    /// Cells across separation and across angle.
    cells: [u32; 2],
}

impl<'f> FocusTable<'f> {
    pub(crate) fn new(focus: &'f [FocusPair], p: &MatchParams) -> FocusTable<'f> {
        let widths = [p.separation_tolerance, p.angle_tolerance];
        // A little wider than the tolerances, so that rounding never leaves out a focus pair
        // the exact tests would take.
        let reach = widths.map(|w| w * 1.001);
        let span = |f: &FocusPair| {
            let around = |v: f64, k: usize| cell_of(v - reach[k], widths[k])..=cell_of(v + reach[k], widths[k]);
            (around(f.separation, 0), around(f.angle, 1))
        };
        let separations = focus.iter().map(|f| *span(f).0.end() + 1).max().unwrap_or(0);
        let cells = [separations, cell_of(std::f64::consts::FRAC_PI_2 + reach[1], widths[1]) + 1];
        // Each focus pair into every cell of its span.
        let mut items = Vec::with_capacity(focus.len() * 4);
        for (k, f) in focus.iter().enumerate() {
            let (seps, angles) = span(f);
            for s in seps {
                items.extend(angles.clone().map(|a| ((s * cells[1] + a) as usize, k as u16)));
            }
        }
        let (starts, listed) = laid_out_by_cell((cells[0] * cells[1]) as usize, items);
        FocusTable { focus, starts, listed, cells }
    }

    /// The cells (separation, angle) that hold a focus pair.
    fn held_cells(&self) -> impl Iterator<Item = [u32; 2]> + '_ {
        let per_row = self.cells[1] as usize;
        let held = self.starts.windows(2).enumerate().filter(|(_, ends)| ends[0] < ends[1]);
        held.map(move |(c, _)| [(c / per_row) as u32, (c % per_row) as u32])
    }

    /// The focus pairs of scene pair `sp`'s cell, in order: every one within the tolerances of
    /// it among them.
    fn near<'t>(&'t self, sp: &ScenePair) -> impl Iterator<Item = &'f FocusPair> + 't {
        let [s, a] = sp.cell;
        let listed: &[u16] = if s < self.cells[0] && a < self.cells[1] {
            let cell = (s * self.cells[1] + a) as usize;
            &self.listed[self.starts[cell] as usize..self.starts[cell + 1] as usize]
        } else {
            &[]
        };
        listed.iter().map(|&k| &self.focus[k as usize])
    }
}

/// `items` (cell, item) laid out by cell, those of a cell in the order given (a counting
/// sort): where each of `cells` cells' items begin in the list (and end where the next cell's
/// begin), and the list.
fn laid_out_by_cell<T: Copy + Default>(cells: usize, items: Vec<(usize, T)>) -> (Vec<u32>, Vec<T>) {
    let mut starts = vec![0u32; cells + 1];
    for &(cell, _) in &items {
        starts[cell + 1] += 1;
    }
    for c in 1..starts.len() {
        starts[c] += starts[c - 1];
    }
    let (mut next, mut listed) = (starts.clone(), vec![T::default(); items.len()]);
    for (cell, item) in items {
        listed[next[cell] as usize] = item;
        next[cell] += 1;
    }
    (starts, listed)
}

/// A [`FocusTable`]'s cells per tolerance, across separation and across angle.
const CELLS_PER_TOLERANCE: u32 = 2;

/// The cell `value` falls in, cells a [`CELLS_PER_TOLERANCE`]th of `tolerance` wide from 0
/// (values below 0 in the first).
fn cell_of(value: f64, tolerance: f64) -> u32 {
    // The cast truncates, which is the floor from 0 up, and saturates (NaN and below 0 to 0):
    // `floor` is a call to the C library on the baseline x86-64 instruction set.
    (value * CELLS_PER_TOLERANCE as f64 / tolerance) as u32
}

/// A fragment's closest approach to its partner may fall this many support distances beyond
/// where the model has it (stereo loses line ends near corners). 4 found the same objects as 3
/// from 12% more hypotheses; 2 lost some.
pub(crate) const FIT_SLACK: f64 = 3.0;

/// Two lines whose directions' cosine is smaller than this are taken as perpendicular: the sign
/// of a scene pair's cosine then says nothing (noise of the angle tolerance's size decides it).
pub(crate) const PERPENDICULAR_COS: f64 = 0.1;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::{Lcg, model};
    use crate::matcher::views::characteristic_views;
    use nalgebra::{Translation3, UnitQuaternion};

    /// `model`'s lines at `pose`, those with `keep(k)`, their ends noised.
    fn lines_at(model: &MatcherModel, pose: &Isometry3<f64>, keep: impl Fn(usize) -> bool, rng: &mut Lcg) -> Vec<Seg> {
        let lines = model.lines.iter().enumerate().filter(|(k, _)| keep(*k));
        lines
            .map(|(_, l)| l.transformed(pose))
            .map(|t| Seg::new(t.a + rng.noise(2e-4), t.b + rng.noise(2e-4)))
            .collect()
    }

    /// The table hands a scene pair every focus pair within the tolerances, in order, as a
    /// search of the focus pairs by separation and a test of their angles does: over random
    /// focus pairs (many at separation 0, as a part's edges meet) and random scene pairs, near
    /// the tolerances' edges too.
    #[test]
    fn the_focus_table_hands_a_scene_pair_the_focus_pairs_within_the_tolerances() {
        let p = MatchParams::default();
        let mut rng = Lcg(3);
        let value = |most: f64, tolerance: f64, rng: &mut Lcg| match (rng.next() * 4.0) as u32 {
            0 => 0.0,
            1 => (rng.next() * most / tolerance).round() * tolerance,
            _ => rng.next() * most,
        };
        let (mut handed, mut within) = (0, 0);
        for _ in 0..50 {
            let mut focus: Vec<FocusPair> = (0..40)
                .map(|k| FocusPair {
                    focus: k,
                    partner: k,
                    angle: value(std::f64::consts::FRAC_PI_2, p.angle_tolerance, &mut rng),
                    separation: value(0.08, p.separation_tolerance, &mut rng),
                    at_focus: 0.0,
                    at_partner: 0.0,
                })
                .collect();
            focus.sort_by(|a, b| a.separation.total_cmp(&b.separation));
            let table = FocusTable::new(&focus, &p);
            for _ in 0..400 {
                let k = (rng.next() * focus.len() as f64) as usize;
                let (near_sep, near_angle) = (rng.next() < 0.5, rng.next() < 0.5);
                let shift = |tolerance: f64, rng: &mut Lcg| (rng.next() * 2.0 - 1.0) * tolerance * 1.2;
                let separation = if near_sep {
                    focus[k].separation + shift(p.separation_tolerance, &mut rng)
                } else {
                    rng.next() * 0.2
                };
                let angle =
                    if near_angle { focus[k].angle + shift(p.angle_tolerance, &mut rng) } else { rng.next() * 1.6 };
                let (separation, angle) = (separation.max(0.0), angle.clamp(0.0, std::f64::consts::FRAC_PI_2));
                let cell = [cell_of(separation, p.separation_tolerance), cell_of(angle, p.angle_tolerance)];
                let sp = ScenePair { j: 0, l: 1, angle, separation, at_j: 0.0, at_l: 0.0, cell };
                let from = focus.partition_point(|f| f.separation < separation - p.separation_tolerance);
                let expected: Vec<usize> = focus[from..]
                    .iter()
                    .take_while(|f| f.separation <= separation + p.separation_tolerance)
                    .filter(|f| (angle - f.angle).abs() <= p.angle_tolerance)
                    .map(|f| f.focus)
                    .collect();
                let tolerance = p.separation_tolerance;
                let found: Vec<usize> = table
                    .near(&sp)
                    .inspect(|_| handed += 1)
                    .filter(|f| f.separation >= separation - tolerance && f.separation <= separation + tolerance)
                    .filter(|f| (angle - f.angle).abs() <= p.angle_tolerance)
                    .map(|f| f.focus)
                    .collect();
                assert_eq!(found, expected, "separation {separation}, angle {angle}");
                within += expected.len();
            }
        }
        // The table hands over few more than those within (cells are half a tolerance wide).
        assert!(within > 2000, "only {within} within the tolerances");
        assert!(handed < 3 * within, "{handed} handed for {within} within");
    }

    /// The pairs worked out once per unordered pair are, bit for bit and in order, those worked
    /// out for every ordered pair on its own.
    #[test]
    fn scene_pairs_worked_out_once_each_way_round_match_each_worked_out_alone() {
        let p = MatchParams::default();
        let mut rng = Lcg(9);
        let scene: Vec<Seg> = (0..40)
            .map(|_| {
                let a = Point3::from(rng.noise(0.1)) + Vector3::new(0.0, 0.0, 0.8);
                Seg::new(a, a + rng.noise(0.05))
            })
            .collect();
        let mut alone = Vec::new();
        for (j, sj) in scene.iter().enumerate().filter(|(_, s)| s.len >= p.min_seed_length) {
            for (l, sl) in scene.iter().enumerate().filter(|(_, s)| s.len >= p.min_seed_length) {
                let angle = line_angle(&sj.dir, &sl.dir);
                if j != l && angle >= 0.3 {
                    let (at_j, at_l) = closest_params(&sj.a, &sj.dir, &sl.a, &sl.dir);
                    alone.push((j, l, angle, separation(&sj.a, &sj.dir, &sl.a, &sl.dir), at_j, at_l));
                }
            }
        }
        let once: Vec<_> =
            scene_pairs(&scene, &p).iter().map(|s| (s.j, s.l, s.angle, s.separation, s.at_j, s.at_l)).collect();
        assert!(alone.len() > 500, "only {} pairs", alone.len());
        assert_eq!(once, alone);
    }

    fn near(a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
        (a.translation.vector - b.translation.vector).norm() < 2e-3 && a.rotation.angle_to(&b.rotation) < 0.035
    }

    /// Two widgets 12 cm apart: the first in full view, the second with a third of its lines.
    /// The first's hypotheses are many and each better supported than any of the second's; the
    /// second's must still be among those kept, or no later search could find it.
    #[test]
    fn a_second_instance_keeps_its_hypotheses_beside_a_better_seen_first() {
        let model = model("widget");
        let p = MatchParams::default();
        let mut rng = Lcg(11);
        let first = Isometry3::from_parts(
            Translation3::new(-0.06, 0.0, 0.85),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 0.5),
        );
        let second = Isometry3::from_parts(
            Translation3::new(0.06, 0.01, 0.86),
            UnitQuaternion::from_euler_angles(-0.4, 0.1, 2.0),
        );
        let mut scene = lines_at(&model, &first, |_| true, &mut rng);
        scene.extend(lines_at(&model, &second, |k| k % 3 == 0, &mut rng));
        let views = characteristic_views(&model, &p);
        let (found, _) = hypotheses(&model, &scene, &scene_pairs(&scene, &p), &views, &p);
        let at_first = found.iter().filter(|(_, pose)| near(pose, &first)).count();
        let best_at_second = found.iter().filter(|(_, pose)| near(pose, &second)).map(|(s, _)| *s).fold(0.0, f64::max);
        let least_at_first =
            found.iter().filter(|(_, pose)| near(pose, &first)).map(|(s, _)| *s).fold(f64::MAX, f64::min);
        assert!(at_first > RECORDED_PER_KEPT * p.hypotheses, "only {at_first} hypotheses at the first");
        assert!(best_at_second > 0.0, "no hypothesis at the second widget");
        assert!(best_at_second < least_at_first, "the second is not the worse seen");
    }
}
