//! PMF stereo matching (Pollard, Mayhew & Frisby 1985, as TINA does it) on rectified edgels.
//!
//! 1. Candidates: right edgels on the left edgel's rectified raster, within the disparity range,
//!    of compatible orientation (accepted under `orientation_accept`, rejected over
//!    `orientation_reject`, between them only if the disparity gradient along the edge they
//!    imply is within `orientation_gradient_limit`), contrast (same sign across the raster,
//!    ratio within `contrast_ratio`) and the grey level beside the edge (alike on one side at
//!    least, within `side_tolerance`, or for an edgel that nothing passes so, within the
//!    pair's own measured scatter: the surface both cameras see). Edgels running nearly
//!    along the raster are not matched: their disparity is ill defined. Where one image shows
//!    a narrow strip of surface beside an edge that the other does not, the nearer surface's
//!    edge takes the match ([`Pair::strip_says`]).
//! 2. Support: each candidate gathers, from every other left edgel within `support_radius`, the
//!    inverse distance to it if one of that edgel's candidates lies within the disparity-gradient
//!    limit of this one (each neighbour counts once, with its best such candidate).
//! 3. Winner takes all, iterated: a candidate strongest for both its left and its right edgel is
//!    accepted and its rivals removed (uniqueness), until nothing changes.
//! 4. Ordering along each raster, then figural continuity along left edge strings, prune what
//!    the local choices let through; figural continuity along the right image's strings
//!    ([`right_figural_continuity`], run by the caller over whole strings) takes back right
//!    edgels a half-occluded left edge borrowed from the occluder's.

use super::canny::Edgel;
use super::photometric::Scatter;
use super::strings::EdgeString;
use super::workspace::DisparityPlane;
use serde::{Deserialize, Serialize};
use strip::{Beside, Pair, Strip};

mod strip;

/// PMF's parameters; they travel to the workers in a control message.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PmfParams {
    /// Disparity range, rectified pixels (`x_left - x_right`).
    pub disparity_min: f32,
    pub disparity_max: f32,
    /// No disparity under this one at the left edgel (the table's top, [`super::workspace`]).
    pub floor: Option<DisparityPlane>,
    /// Orientation differences (radians) always accepted / always rejected.
    pub orientation_accept: f32,
    pub orientation_reject: f32,
    /// Disparity gradient along an edge allowed for orientation differences in between.
    pub orientation_gradient_limit: f32,
    /// Contrast ratio range, right over left. A crease between two matte faces has the same
    /// contrast from both cameras (their shading does not depend on where they are seen from),
    /// so only noise and silhouettes, whose background differs between the views, spread the
    /// ratio. Chosen on tuning seeds (`marvin eval vision|locate worlds/widgets.toml`, seeds
    /// 1-20, 101-120, 2001-2020 and 1-50, 101-200, 2001-2050), before `side_tolerance`: (0.2, 5)
    /// -> (0.5, 2) took the 3D lines' coverage up 1.0-1.4 points and matches within 0.5 px up
    /// 0.1-0.4; objects located 95.7 / 94.6 / 94.2% -> 96.0 / 95.5 / 94.8% with 3 / 8 / 3 -> 4
    /// / 5 / 2 false reports; (0.33, 3) gained half as much; (0.67, 1.5) gave 96.3-96.8% within
    /// 0.5 px but 0.4-0.7 points less coverage than (0.2, 5) and located fewer objects.
    pub contrast_ratio: (f32, f32),
    /// Edgels whose tangent lies within this angle (radians) of the raster are not matched.
    pub min_angle_to_raster: f32,
    /// Grey levels by which the image beside an edge (see [`Edgel::sides`]) may differ between
    /// the two images on the side that matches. Matte surfaces look alike from both cameras,
    /// which share their gain; the smoothed sensor noise is about 0.5 grey levels. Chosen on
    /// tuning seeds with `contrast_ratio` (0.5, 2) (`marvin eval vision worlds/widgets.toml
    /// --scenes 20`, seeds 1 / 101 / 2001; coverage and within 0.5 px): none 72.0 / 74.6 /
    /// 72.5% and 95.8 / 95.9 / 95.4%; 4: 73.3 / 75.1 / 73.9% and 95.9 / 95.9 / 95.6%; 3: 73.4
    /// / 75.1 / 74.0% and 96.1 / 95.9 / 95.7%; 2: 73.2 / 75.0 / 73.8% and 96.4 / 96.1 / 95.9%,
    /// but 2 located fewer objects than 3 (`eval locate --scenes 50`, seeds 1, 101, 2001, and
    /// `dense.toml`) with more false reports.
    pub side_tolerance: f32,
    /// The pair's own scatter of one surface's grey levels about their photometric relation
    /// ([`super::photometric::Scatter`]), which [`pmf`] measures on the pair. A left edgel
    /// that no right edgel passes within `side_tolerance` is judged again with the sides
    /// allowed [`SIDE_DEVIATIONS`] of it, where that is wider: under a lamp that shows glossy
    /// faces brighter to one camera, a whole part's edges can fail the test by 4-8 grey levels
    /// (seed 7038 of `dense.toml` imaged by `tools/other_renderer.py`: a wedge's slope face at
    /// 202 in the left image and 205-210 in the right, none of its edgels matched). The
    /// looser test is kept for such edgels alone: for every edgel, it located fewer parts in
    /// the cell's own images (`marvin eval locate worlds/dense.toml --scenes 150 --seed 6401`:
    /// 0.931 -> 0.927, false reports 17 -> 21; docs/TUNING.md, session 76).
    #[serde(skip)]
    pub side_scatter: Scatter,
    /// Widest strip of surface (pixels along the raster) beside an edge that one camera may see
    /// and the other not ([`Pair::strip_says`]). Chosen on tuning seeds (`marvin eval vision
    /// worlds/widgets.toml --scenes 50`, seeds 1 / 101; within 0.5 px and coverage): none 95.5 /
    /// 95.3% and 76.5 / 76.1%; 8 px 95.9 / 95.6% and 77.0 / 76.4%; 10 px 96.0 / 95.8% and 76.9
    /// / 76.5%; 14 px 96.0 / 95.8% and 76.9 / 76.3% (a first form of the test: see
    /// `strip::STRIP_TOLERANCE` for what the final one keeps).
    pub one_view_strip_px: f32,
    /// The strip's widest as a share of the candidate's disparity, where that is wider than
    /// `one_view_strip_px`. A face seen by one camera only is seen by the other about
    /// `baseline / depth` from edge-on, so its width in the image is its extent in depth times
    /// `f baseline / depth^2`: its disparity times `extent / depth`. The parts' faces reach
    /// about 5% of their distance (45 mm at 0.9 m); `side_light.toml`'s rig, nearer and
    /// steeper, shows them wider (a block's lit end 19 px, seed 52) than `widgets.toml`'s. Against 10 px
    /// alone, on `marvin eval vision --scenes 50` seeds 1 / 101 (within 0.5 px, coverage):
    /// `side_light.toml` 93.40 / 93.02% -> 93.85 / 93.60%, 68.0 / 66.6% -> 68.0 / 66.8%,
    /// `widgets.toml` 96.48 / 96.25% -> 96.47 / 96.29%, 76.8 / 76.3% -> 76.8 / 76.3%,
    /// `dense.toml` (101) 95.61 -> 95.66%; `eval locate` on the tuning seeds (`widgets.toml`
    /// 1-500, `dense.toml` and `side_light.toml` 1-200) 98.04 / 91.42 / 93.60% with 9 / 18 / 4
    /// false reports -> 98.04 / 91.35 / 93.88% with 10 / 18 / 4. (A fixed 14 px gave 98.01 /
    /// 91.35 / 93.96% with 11 / 18 / 5.)
    pub one_view_strip_per_disparity: f32,
    pub support_radius: f32,
    pub disparity_gradient_limit: f32,
    /// Largest disparity step between consecutive matched edgels of a string (figural continuity).
    pub continuity_step: f32,
}

impl Default for PmfParams {
    fn default() -> Self {
        PmfParams {
            disparity_min: 0.0,
            disparity_max: 512.0,
            floor: None,
            orientation_accept: 0.3,
            orientation_reject: 1.0,
            orientation_gradient_limit: 1.0,
            contrast_ratio: (0.5, 2.0),
            min_angle_to_raster: 0.35,
            side_tolerance: 3.0,
            side_scatter: Scatter::default(),
            one_view_strip_px: 10.0,
            one_view_strip_per_disparity: 0.05,
            support_radius: 20.0,
            disparity_gradient_limit: 0.5,
            continuity_step: 1.0,
        }
    }
}

/// A stereo match, at the left edgel's rectified position.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Match {
    /// Indices into the left and right (rectified) edgel lists.
    pub left: u32,
    pub right: u32,
    pub x: f32,
    pub y: f32,
    pub disparity: f32,
    pub strength: f32,
}

#[derive(Debug, Clone, Copy)]
struct Candidate {
    right: u32,
    disparity: f32,
    strength: f32,
    alive: bool,
}

pub(crate) fn angle_diff(a: f32, b: f32) -> f32 {
    use std::f32::consts::{PI, TAU};
    ((a - b + PI).rem_euclid(TAU) - PI).abs()
}

/// `dx/dy` along an edge with gradient direction `orientation` (its tangent is `(-sin, cos)`).
fn slope(orientation: f32) -> f32 {
    let (s, c) = orientation.sin_cos();
    -s / c
}

/// Rectified edgels bucketed by raster (`round(y)`), for finding candidates and neighbours.
struct Rasters {
    first_row: i32,
    rows: Vec<Vec<u32>>,
}

impl Rasters {
    fn new(edgels: &[Edgel]) -> Rasters {
        let row = |e: &Edgel| e.y.round() as i32;
        let first_row = edgels.iter().map(row).min().unwrap_or(0);
        let last_row = edgels.iter().map(row).max().unwrap_or(-1);
        let mut rows = vec![Vec::new(); (last_row - first_row + 1).max(0) as usize];
        for (i, e) in edgels.iter().enumerate() {
            rows[(row(e) - first_row) as usize].push(i as u32);
        }
        Rasters { first_row, rows }
    }

    fn row(&self, r: i32) -> &[u32] {
        let k = r - self.first_row;
        if k < 0 || k as usize >= self.rows.len() { &[] } else { &self.rows[k as usize] }
    }
}

/// Matches rectified left edgels to rectified right edgels: once without comparing the grey
/// levels beside them, to measure the cameras' photometric relation from those matches
/// ([`super::photometric`]), then again with the right edgels' grey levels mapped through it.
pub fn pmf(left: &[Edgel], right: &[Edgel], left_strings: &[EdgeString], p: &PmfParams) -> Vec<Match> {
    let relation = photometric_relation(left, right, left_strings, p);
    let right: Vec<Edgel> = right.iter().map(|e| relation.map(e)).collect();
    pmf_once(left, &right, left_strings, &PmfParams { side_scatter: relation.scatter, ..*p })
}

/// The cameras' photometric relation as [`pmf`] measures it: from a first pass without the
/// side test.
pub fn photometric_relation(
    left: &[Edgel],
    right: &[Edgel],
    left_strings: &[EdgeString],
    p: &PmfParams,
) -> super::photometric::Relation {
    let first = pmf_once(left, right, left_strings, &PmfParams { side_tolerance: f32::INFINITY, ..*p });
    super::photometric::from_matches(left, right, first.iter().map(|m| (m.left, m.right)))
}

/// One pass of PMF, the grey levels beside the edgels taken as they are.
fn pmf_once(left: &[Edgel], right: &[Edgel], left_strings: &[EdgeString], p: &PmfParams) -> Vec<Match> {
    let (offsets, mut cands) = candidates(left, right, p);
    let has_candidates: Vec<bool> = (0..left.len()).map(|l| offsets[l + 1] > offsets[l]).collect();
    let neighbours = neighbourhoods(left, &has_candidates, p.support_radius, p.disparity_gradient_limit);
    let owner: Vec<u32> =
        (0..left.len()).flat_map(|l| std::iter::repeat_n(l as u32, offsets[l + 1] - offsets[l])).collect();
    let mut matches = winner_takes_all(left, right, &offsets, &mut cands, |cands: &mut [Candidate], done: &[bool]| {
        support(&offsets, &owner, cands, &neighbours, done)
    });
    enforce_ordering(&mut matches);
    figural_continuity(&mut matches, left.len(), left_strings, p.continuity_step);
    matches
}

/// What candidate selection asks of an edgel, worked out once per edgel rather than once per
/// pair: each pair used to take a sine and cosine of both edgels' orientations.
#[derive(Debug, Clone, Copy)]
struct Shape {
    /// `dx/dy` along the edge.
    slope: f32,
    /// Runs too nearly along the raster to be matched.
    flat: bool,
    /// Brighter to the right: the sign of the gradient's x component.
    bright_right: bool,
}

fn shapes(edgels: &[Edgel], p: &PmfParams) -> Vec<Shape> {
    let steepest_flat = 1.0 / p.min_angle_to_raster.tan();
    edgels
        .iter()
        .map(|e| {
            let slope = slope(e.orientation);
            Shape { slope, flat: slope.abs() > steepest_flat, bright_right: e.orientation.cos() > 0.0 }
        })
        .collect()
}

/// Whether the grey level on at least one side of the edge is alike in both images (within
/// [`side_tolerance_at`]): the surface nearer the cameras at a silhouette, or both faces at a
/// crease, look the same from both cameras; an edge matched to another edge in general does not.
fn one_surface_alike(l: &Edgel, r: &Edgel, p: &PmfParams) -> bool {
    (0..2).any(|i| (l.sides[i] - r.sides[i]).abs() <= side_tolerance_at(l.sides[i], p))
}

/// How many of the pair's own deviations ([`PmfParams::side_scatter`]) one surface's two grey
/// levels may differ by. Chosen on tuning seeds 7001-7040 (`marvin eval pairs`, the other
/// renderer's piled parts; docs/TUNING.md, session 76): 2, 3 and 4 located 0.8891, 0.8945 and
/// 0.8927 (0.8784 without), the cell's own images of the same scenes 0.9338, 0.9374, 0.9374.
pub const SIDE_DEVIATIONS: f32 = 3.0;

/// The side test's tolerance at left grey level `grey`: `side_tolerance`, or more where the
/// pair's grey levels scatter more.
fn side_tolerance_at(grey: f32, p: &PmfParams) -> f32 {
    p.side_tolerance.max(SIDE_DEVIATIONS * p.side_scatter.at(grey))
}

/// Why a right edgel is not a candidate for a left one: the tests of candidate selection, in
/// the order they are made. `marvin eval vision` counts them for the left edgels left unmatched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Refusal {
    /// The left edgel runs too nearly along the raster.
    NearRaster,
    /// No right edgel on the raster near the disparity asked about (none found, or it runs
    /// along the raster).
    NoPartner,
    OutOfRange,
    ContrastSign,
    ContrastRatio,
    Sides,
    Orientation,
}

/// The disparity at which right edgel `r` is a candidate for left edgel `l`, or the first test
/// it fails (the right edgel is on `l`'s raster band and does not run along it).
fn judge(l: &Edgel, ls: &Shape, r: &Edgel, rs: &Shape, p: &PmfParams) -> Result<f32, Refusal> {
    // Where the right edge crosses the left edgel's raster.
    let disparity = l.x - (r.x + (l.y - r.y) * rs.slope);
    let under_floor = p.floor.is_some_and(|f| disparity < f.at(l.x, l.y));
    if disparity < p.disparity_min || disparity > p.disparity_max || under_floor {
        return Err(Refusal::OutOfRange);
    }
    // Contrast sign across the raster.
    if ls.bright_right != rs.bright_right {
        return Err(Refusal::ContrastSign);
    }
    let ratio = r.contrast / l.contrast;
    if ratio < p.contrast_ratio.0 || ratio > p.contrast_ratio.1 {
        return Err(Refusal::ContrastRatio);
    }
    if !one_surface_alike(l, r, p) {
        return Err(Refusal::Sides);
    }
    let turn = angle_diff(l.orientation, r.orientation);
    let along_edge_gradient = (ls.slope - rs.slope).abs();
    let compatible = turn < p.orientation_accept
        || (turn <= p.orientation_reject && along_edge_gradient <= p.orientation_gradient_limit);
    if compatible { Ok(disparity) } else { Err(Refusal::Orientation) }
}

fn candidates(left: &[Edgel], right: &[Edgel], p: &PmfParams) -> (Vec<usize>, Vec<Candidate>) {
    let rasters = Rasters::new(right);
    let (left_shape, right_shape) = (shapes(left, p), shapes(right, p));
    let images = Pair { left: Beside::new(left, &left_shape), right: Beside::new(right, &right_shape) };
    let right = RightImage { edgels: right, shapes: &right_shape, rasters: &rasters, images: &images };
    // The sides judged within `side_tolerance` first; a left edgel left with no candidate at
    // all is judged again within the pair's own scatter (`side_scatter`).
    let strict = PmfParams { side_scatter: Scatter::default(), ..*p };
    let mut offsets = Vec::with_capacity(left.len() + 1);
    let mut out = Vec::new();
    for (l, ls) in left.iter().zip(&left_shape) {
        offsets.push(out.len());
        if ls.flat {
            continue;
        }
        let start = out.len();
        right.push_candidates((l, ls), &strict, &mut out);
        if out.len() == start && p.side_scatter != strict.side_scatter {
            right.push_candidates((l, ls), p, &mut out);
        }
    }
    offsets.push(out.len());
    (offsets, out)
}

/// The right image as candidate selection reads it.
struct RightImage<'a> {
    edgels: &'a [Edgel],
    shapes: &'a [Shape],
    rasters: &'a Rasters,
    /// Both images' greys beside their edgels, for the strip test.
    images: &'a Pair,
}

impl RightImage<'_> {
    /// Pushes onto `out` left edgel `l`'s candidates among the right edgels on its raster.
    fn push_candidates(&self, (l, ls): (&Edgel, &Shape), p: &PmfParams, out: &mut Vec<Candidate>) {
        let row = l.y.round() as i32;
        let rasters = self.rasters;
        for &ri in rasters.row(row - 1).iter().chain(rasters.row(row)).chain(rasters.row(row + 1)) {
            let (r, rs) = (&self.edgels[ri as usize], &self.shapes[ri as usize]);
            if (r.y - l.y).abs() > 0.5 || rs.flat {
                continue;
            }
            let verdict = match judge(l, ls, r, rs, p) {
                Err(Refusal::ContrastRatio) if self.images.strip_says((l, ls), (r, rs), p) == Some(Strip::Excuses) => {
                    // The contrasts' ratio is excused as far as the steps' grey levels explain it
                    // (the other image's step spans the strip's too).
                    let expected = (r.sides[1] - r.sides[0]).abs() / (l.sides[1] - l.sides[0]).abs().max(1.0);
                    let (lo, hi) = p.contrast_ratio;
                    judge(l, ls, r, rs, &PmfParams { contrast_ratio: (lo * expected, hi * expected), ..*p })
                }
                v => v,
            };
            let Ok(disparity) = verdict else { continue };
            if self.images.strip_says((l, ls), (r, rs), p) == Some(Strip::Refuses) {
                continue;
            }
            out.push(Candidate { right: ri, disparity, strength: 0.0, alive: true });
        }
    }
}

/// Why left edgel `l` has no candidate within `within` px of `disparity` among `right` (all
/// rectified): the test that the right edgels there came furthest through before failing, or
/// `None` if one of them is a candidate. For diagnosis; it scans every right edgel. The sides
/// are judged within the pair's scatter (`p.side_scatter`) as PMF judges an edgel that nothing
/// passes strictly, even where PMF found such a candidate elsewhere on the raster.
pub fn refusal(l: &Edgel, right: &[Edgel], disparity: f32, within: f32, p: &PmfParams) -> Option<Refusal> {
    let shape = |e: &Edgel| shapes(std::slice::from_ref(e), p)[0];
    let ls = shape(l);
    if ls.flat {
        return Some(Refusal::NearRaster);
    }
    let mut furthest = Refusal::NoPartner;
    for r in right.iter().filter(|r| (r.y - l.y).abs() <= 0.5) {
        let rs = shape(r);
        let crossing = l.x - (r.x + (l.y - r.y) * rs.slope);
        if rs.flat || (crossing - disparity).abs() > within {
            continue;
        }
        match judge(l, &ls, r, &rs, p) {
            Ok(_) => return None,
            Err(why) => furthest = furthest.max(why),
        }
    }
    Some(furthest)
}

/// A neighbour of a left edgel, as its candidates' support needs it.
#[derive(Debug, Clone, Copy)]
struct Neighbour {
    edgel: u32,
    /// Inverse distance: what one supporting neighbour adds.
    weight: f32,
    /// The disparity differences (neighbour's minus this one's) within the disparity-gradient
    /// limit, measured in the cyclopean image: `|D| <= k sqrt((dx - D/2)^2 + dy^2)` is
    /// a quadratic in `D` with roots `lo` and `hi`, so this is worked out once per pair.
    lo: f32,
    hi: f32,
}

/// Every left edgel's neighbours, one list after another: one allocation, not one per edgel.
struct Neighbourhoods {
    /// Edgel `l`'s neighbours are `all[start[l]..start[l + 1]]`.
    start: Vec<u32>,
    all: Vec<Neighbour>,
}

impl Neighbourhoods {
    fn of(&self, l: usize) -> &[Neighbour] {
        &self.all[self.start[l] as usize..self.start[l + 1] as usize]
    }
}

/// For each left edgel with candidates, the other such edgels within `radius`.
fn neighbourhoods(left: &[Edgel], has_candidates: &[bool], radius: f32, limit: f32) -> Neighbourhoods {
    let cell = radius.max(1.0);
    let key = |e: &Edgel| ((e.x / cell).floor() as i32, (e.y / cell).floor() as i32);
    // A dense grid of cells a radius wide over the edgels' extent (hashing the cells was a
    // fifth of PMF's time).
    let (mut lo, mut hi) = ((i32::MAX, i32::MAX), (i32::MIN, i32::MIN));
    for e in left {
        let (cx, cy) = key(e);
        (lo, hi) = ((lo.0.min(cx), lo.1.min(cy)), (hi.0.max(cx), hi.1.max(cy)));
    }
    let (columns, rows) = ((hi.0 - lo.0 + 1).max(0) as usize, (hi.1 - lo.1 + 1).max(0) as usize);
    let mut cells: Vec<Vec<u32>> = vec![Vec::new(); columns * rows];
    let cell_of = |cx: i32, cy: i32| -> Option<usize> {
        let (x, y) = (cx - lo.0, cy - lo.1);
        (x >= 0 && y >= 0 && (x as usize) < columns && (y as usize) < rows).then(|| y as usize * columns + x as usize)
    };
    for (i, e) in left.iter().enumerate().filter(|(i, _)| has_candidates[*i]) {
        let (cx, cy) = key(e);
        if let Some(c) = cell_of(cx, cy) {
            cells[c].push(i as u32);
        }
    }
    let k2 = limit * limit;
    let a = 1.0 - k2 / 4.0;
    // Squared distances a little beyond the radius are let through to the exact test below.
    let reach2 = radius * radius * 1.001;
    let mut out = Neighbourhoods { start: Vec::with_capacity(left.len() + 1), all: Vec::new() };
    for (i, e) in left.iter().enumerate() {
        out.start.push(out.all.len() as u32);
        if !has_candidates[i] {
            continue;
        }
        let (cx, cy) = key(e);
        for gy in cy - 1..=cy + 1 {
            for gx in cx - 1..=cx + 1 {
                for &j in cell_of(gx, gy).map_or(&[][..], |c| cells[c].as_slice()) {
                    let o = &left[j as usize];
                    let (dx, dy) = (o.x - e.x, o.y - e.y);
                    let dist2 = dx * dx + dy * dy;
                    if j as usize == i || dist2 > reach2 {
                        continue;
                    }
                    let dist = dist2.sqrt();
                    if dist > radius {
                        continue;
                    }
                    // a D^2 + b D + c <= 0, a = 1 - k^2/4, b = k^2 dx, c = -k^2 (dx^2 + dy^2).
                    let (b, c) = (k2 * dx, -k2 * dist * dist);
                    let root = (b * b - 4.0 * a * c).sqrt();
                    out.all.push(Neighbour {
                        edgel: j,
                        weight: 1.0 / dist,
                        lo: (-b - root) / (2.0 * a),
                        hi: (-b + root) / (2.0 * a),
                    });
                }
            }
        }
    }
    out.start.push(out.all.len() as u32);
    out
}

/// Each live candidate's support from the live candidates around it (left edgels in `done`
/// already have their match and keep their strength). `owner[c]` is candidate `c`'s left edgel.
fn support(offsets: &[usize], owner: &[u32], cands: &mut [Candidate], neighbours: &Neighbourhoods, done: &[bool]) {
    use rayon::prelude::*;
    let cands_now: &[Candidate] = cands;
    // The new strengths, computed in parallel (they only read), in blocks big enough to be
    // worth a task each.
    let strengths: Vec<f32> = (0..cands_now.len())
        .into_par_iter()
        .with_min_len(256)
        .map(|c| {
            let (l, d) = (owner[c] as usize, cands_now[c].disparity);
            if done[l] {
                return cands_now[c].strength;
            }
            let mut total = 0.0;
            for nb in neighbours.of(l) {
                let n = nb.edgel as usize;
                let theirs = &cands_now[offsets[n]..offsets[n + 1]];
                if theirs.iter().any(|nc| nc.alive && (nb.lo..=nb.hi).contains(&(nc.disparity - d))) {
                    total += nb.weight;
                }
            }
            total
        })
        .collect();
    for (c, v) in cands.iter_mut().zip(strengths) {
        c.strength = v;
    }
}

/// Accepts, round after round, the candidates strongest for both their edgels, removing their
/// rivals and re-evaluating support (`support`) among what is left before each round.
fn winner_takes_all(
    left: &[Edgel],
    right: &[Edgel],
    offsets: &[usize],
    cands: &mut [Candidate],
    mut support: impl FnMut(&mut [Candidate], &[bool]),
) -> Vec<Match> {
    // Candidates of each right edgel, to find a candidate's rivals there.
    let mut by_right: Vec<Vec<(u32, usize)>> = vec![Vec::new(); right.len()];
    for l in 0..left.len() {
        for c in offsets[l]..offsets[l + 1] {
            by_right[cands[c].right as usize].push((l as u32, c));
        }
    }
    let strongest = |cs: &[Candidate], ids: &mut dyn Iterator<Item = usize>| -> Option<usize> {
        ids.filter(|&c| cs[c].alive).max_by(|&a, &b| cs[a].strength.total_cmp(&cs[b].strength).then(b.cmp(&a)))
    };
    let mut matches = Vec::new();
    let mut matched_left = vec![false; left.len()];
    let mut last_accepted = left.len();
    loop {
        // Support is re-evaluated while rounds still settle much; late rounds that accept only
        // a few stragglers keep the strengths they have (it changes nothing measurable and
        // costs a full pass each).
        if last_accepted * 50 >= left.len() {
            support(cands, &matched_left);
        }
        let mut accepted = Vec::new();
        for l in 0..left.len() {
            if matched_left[l] {
                continue;
            }
            let Some(best) = strongest(cands, &mut (offsets[l]..offsets[l + 1])) else {
                continue;
            };
            let r = cands[best].right as usize;
            if strongest(cands, &mut by_right[r].iter().map(|&(_, c)| c)) == Some(best) {
                accepted.push((l, best));
            }
        }
        if accepted.is_empty() {
            return matches;
        }
        last_accepted = accepted.len();
        for (l, best) in accepted {
            let r = cands[best].right as usize;
            // The winner stays alive: it supports its neighbours in later rounds.
            for c in (offsets[l]..offsets[l + 1]).chain(by_right[r].iter().map(|&(_, c)| c)) {
                cands[c].alive = c == best;
            }
            matched_left[l] = true;
            let e = &left[l];
            matches.push(Match {
                left: l as u32,
                right: r as u32,
                x: e.x,
                y: e.y,
                disparity: cands[best].disparity,
                strength: cands[best].strength,
            });
        }
    }
}

/// Along each raster, matches must keep their left-to-right order in both images: of two that
/// cross, the weaker goes.
fn enforce_ordering(matches: &mut Vec<Match>) {
    let mut order: Vec<usize> = (0..matches.len()).collect();
    order.sort_by(|&a, &b| matches[b].strength.total_cmp(&matches[a].strength));
    let mut kept: std::collections::HashMap<i32, Vec<(f32, f32)>> = std::collections::HashMap::new();
    let mut keep = vec![false; matches.len()];
    for i in order {
        let m = &matches[i];
        let row = kept.entry(m.y.round() as i32).or_default();
        let xr = m.x - m.disparity;
        let crosses = row.iter().any(|&(ol, or)| (ol - m.x) * (or - xr) < 0.0);
        if !crosses {
            row.push((m.x, xr));
            keep[i] = true;
        }
    }
    let mut k = keep.into_iter();
    matches.retain(|_| k.next().unwrap_or(false));
}

/// Keeps a match only if a matched edgel within two steps along its left string agrees with it
/// in disparity (within `step` per string step): isolated matches are usually wrong.
fn figural_continuity(matches: &mut Vec<Match>, n_left: usize, strings: &[EdgeString], step: f32) {
    let mut disparity_of = vec![f32::NAN; n_left];
    for m in matches.iter() {
        disparity_of[m.left as usize] = m.disparity;
    }
    let mut continuous = vec![false; n_left];
    for s in strings {
        let e = &s.edgels;
        for k in 0..e.len() {
            let d = disparity_of[e[k] as usize];
            if d.is_nan() {
                continue;
            }
            let lo = k.saturating_sub(2);
            let hi = (k + 2).min(e.len() - 1);
            continuous[e[k] as usize] = (lo..=hi).any(|j| {
                let dj = disparity_of[e[j] as usize];
                j != k && !dj.is_nan() && (dj - d).abs() <= step * (j.abs_diff(k) as f32)
            });
        }
    }
    matches.retain(|m| continuous[m.left as usize]);
}

/// Figural continuity along the right image's strings: where consecutive matched edgels of one
/// right string take partners from two different left strings with a disparity jump between
/// them, the left string with more matches on that right string (the winner) keeps the right
/// string's edgels, and the other loses its matches on it at each raster where the winner has
/// an edgel at its own disparity (within [`RIGHT_CONTINUITY_PX`]).
///
/// Why: an edge the right camera sees differently or not at all (half-occluded by a nearer part,
/// or a silhouette against another background) may find no partner that PMF accepts, and PMF
/// gives its left edgels the right edgels of the occluding edge beside it, which their
/// neighbours support at the occluder's disparity. The occluder's own edge in the left image
/// owns those right edgels along the rest of the right string; where it has no edgel on the
/// raster (a right string running on round a junction onto another edge) the matches stand.
/// On tuning seeds (`marvin eval vision worlds/widgets.toml --scenes 20 --seed S`), within
/// 0.5 px / wrong / coverage before and after: seeds 1-20 95.37 / 1.34 / 70.6% -> 95.64 / 1.20
/// / 71.5%; 101-120 95.27 / 1.56 / 73.2% -> 95.45 / 1.39 / 73.9%; 2001-2020 95.18 / 1.36 /
/// 72.0% -> 95.27 / 1.28 / 71.7% (measured before the side test in candidate selection).
/// Dropping the loser's matches on the whole right string instead cost 2.2 points of coverage;
/// giving the right edgel to the winner's unmatched edgel gained nothing. Most wrong lines were
/// left: their true partner was there but PMF refused it (a silhouette's contrast 4 on the left
/// against 40 on the right, beyond the contrast ratio of then) or preferred another on support;
/// the side test (`side_tolerance`) is what came of that.
pub fn right_figural_continuity(
    matches: &mut Vec<Match>,
    (left, left_strings): (&[Edgel], &[EdgeString]),
    (right, right_strings): (&[Edgel], &[EdgeString]),
    step: f32,
) {
    let mut left_string = vec![u32::MAX; left.len()];
    for (k, st) in left_strings.iter().enumerate() {
        for &i in &st.edgels {
            left_string[i as usize] = k as u32;
        }
    }
    let mut match_of_right = vec![u32::MAX; right.len()];
    for (k, m) in matches.iter().enumerate() {
        match_of_right[m.right as usize] = k as u32;
    }
    let mut gone = vec![false; matches.len()];
    for st in right_strings {
        let along: Vec<(usize, usize)> = st
            .edgels
            .iter()
            .enumerate()
            .filter(|(_, r)| match_of_right[**r as usize] != u32::MAX)
            .map(|(k, r)| (k, match_of_right[*r as usize] as usize))
            .collect();
        let owner = |m: usize| left_string[matches[m].left as usize];
        let count = |ls: u32| along.iter().filter(|(_, m)| owner(*m) == ls).count();
        for w in along.windows(2) {
            let ((ka, ma), (kb, mb)) = (w[0], w[1]);
            let (la, lb) = (owner(ma), owner(mb));
            let jump = (matches[ma].disparity - matches[mb].disparity).abs();
            if la == lb || la == u32::MAX || lb == u32::MAX || jump <= step * (kb - ka) as f32 {
                continue;
            }
            let (winner, loser, winner_disparity) =
                if count(la) >= count(lb) { (la, lb, matches[ma].disparity) } else { (lb, la, matches[mb].disparity) };
            for &(_, m) in along.iter().filter(|(_, m)| owner(*m) == loser) {
                let r = &right[matches[m].right as usize];
                let winner_there = left_strings[winner as usize].edgels.iter().any(|&i| {
                    let e = &left[i as usize];
                    (e.y - r.y).abs() < 0.5 && ((e.x - r.x) - winner_disparity).abs() <= RIGHT_CONTINUITY_PX
                });
                gone[m] |= winner_there;
            }
        }
    }
    let mut k = 0;
    matches.retain(|_| {
        k += 1;
        !gone[k - 1]
    });
}

/// How near (pixels) the winner's own disparity an edgel of it on a raster must lie to own the
/// right edgel there ([`right_figural_continuity`]); 1 px and 3 px gave 0.1-0.2 points less
/// coverage on the same seeds.
pub const RIGHT_CONTINUITY_PX: f32 = 2.0;

#[cfg(test)]
mod tests;
