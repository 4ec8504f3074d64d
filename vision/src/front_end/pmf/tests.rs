//! Tests of PMF matching, beside it (kept apart to keep `pmf.rs` readable).

use super::*;

/// Edgels along a straight edge from `(x0, y0)` running `dx_per_row` per raster, one a row.
fn edge(x0: f32, y0: i32, rows: i32, dx_per_row: f32, bright_right: bool) -> Vec<Edgel> {
    // Tangent (dx, 1) per row; gradient perpendicular, pointing to the bright side.
    let t = (dx_per_row, 1.0f32);
    let g = if bright_right { (t.1, -t.0) } else { (-t.1, t.0) };
    (0..rows)
        .map(|k| Edgel {
            x: x0 + dx_per_row * k as f32,
            y: (y0 + k) as f32,
            orientation: g.1.atan2(g.0),
            contrast: 20.0,
            sides: [0.0, 40.0],
        })
        .collect()
}

fn strings_of(lengths: &[usize]) -> Vec<EdgeString> {
    let mut start = 0u32;
    lengths
        .iter()
        .map(|&n| {
            let s = EdgeString { edgels: (start..start + n as u32).collect() };
            start += n as u32;
            s
        })
        .collect()
}

#[test]
fn refusal_names_the_test_a_partner_fails() {
    let p = PmfParams { disparity_min: 0.0, disparity_max: 100.0, ..PmfParams::default() };
    let l = edge(100.0, 10, 1, 0.2, true)[0];
    let partner = edge(60.0, 10, 1, 0.2, true)[0];
    assert_eq!(refusal(&l, &[partner], 40.0, 1.0, &p), None);
    // Nothing near the disparity asked about, or only something 5 px off.
    assert_eq!(refusal(&l, &[], 40.0, 1.0, &p), Some(Refusal::NoPartner));
    assert_eq!(refusal(&l, &[partner], 45.0, 1.0, &p), Some(Refusal::NoPartner));
    // Dark to the right where the left edge is bright to the right.
    let flipped = edge(60.0, 10, 1, 0.2, false)[0];
    assert_eq!(refusal(&l, &[flipped], 40.0, 1.0, &p), Some(Refusal::ContrastSign));
    let faint = Edgel { contrast: 5.0, ..partner };
    assert_eq!(refusal(&l, &[faint], 40.0, 1.0, &p), Some(Refusal::ContrastRatio));
    let other_surfaces = Edgel { sides: [20.0, 60.0], ..partner };
    assert_eq!(refusal(&l, &[other_surfaces], 40.0, 1.0, &p), Some(Refusal::Sides));
    // Of several would-be partners, the one that came furthest names the refusal.
    assert_eq!(refusal(&l, &[flipped, other_surfaces], 40.0, 1.0, &p), Some(Refusal::Sides));
    let far = PmfParams { disparity_min: 50.0, ..p };
    assert_eq!(refusal(&l, &[partner], 40.0, 1.0, &far), Some(Refusal::OutOfRange));
    let along_raster = edge(100.0, 10, 1, 10.0, true)[0];
    assert_eq!(refusal(&along_raster, &[partner], 40.0, 1.0, &p), Some(Refusal::NearRaster));
}

#[test]
fn each_edge_finds_its_own_disparity_among_lookalikes() {
    // Three parallel edges of the same contrast: every left edge has three candidates in the
    // range, and only the true disparities make the neighbourhood consistent.
    let truth = [(100.0, 40.0), (118.0, 43.0), (140.0, 41.0)];
    let mut left = Vec::new();
    let mut right = Vec::new();
    for &(x, d) in &truth {
        left.extend(edge(x, 10, 30, 0.2, true));
        right.extend(edge(x - d, 10, 30, 0.2, true));
    }
    // A crossing edge ties the three together, as an object's corners do.
    left.extend(edge(95.0, 41, 10, 5.0, false));
    right.extend(edge(95.0 - 41.0, 41, 10, 5.0, false));
    let strings = strings_of(&[30, 30, 30, 10]);
    let p = PmfParams { disparity_min: 20.0, disparity_max: 80.0, ..PmfParams::default() };
    let matches = pmf(&left, &right, &strings, &p);
    assert!(matches.len() >= 80, "only {} of 90 edgels matched", matches.len());
    for m in &matches {
        let expected = if m.left < 90 { truth[m.left as usize / 30].1 } else { 41.0 };
        assert!((m.disparity - expected).abs() < 1e-3, "edgel {} matched at {} not {expected}", m.left, m.disparity);
    }
    // Uniqueness: no right edgel is used twice.
    let mut rights: Vec<u32> = matches.iter().map(|m| m.right).collect();
    rights.sort();
    rights.dedup();
    assert_eq!(rights.len(), matches.len());
}

#[test]
fn opposite_contrast_and_horizontal_edges_never_match() {
    let left = edge(100.0, 10, 20, 0.0, true);
    let flipped = edge(60.0, 10, 20, 0.0, false);
    let strings = strings_of(&[20]);
    let p = PmfParams { disparity_min: 20.0, disparity_max: 80.0, ..PmfParams::default() };
    assert!(pmf(&left, &flipped, &strings, &p).is_empty());
    // An edge along the rasters has no defined disparity.
    let flat: Vec<Edgel> = (0..20)
        .map(|k| Edgel {
            x: 100.0 + k as f32,
            y: 10.0,
            orientation: std::f32::consts::FRAC_PI_2,
            contrast: 20.0,
            sides: [0.0; 2],
        })
        .collect();
    let flat_right: Vec<Edgel> = flat.iter().map(|e| Edgel { x: e.x - 40.0, ..*e }).collect();
    assert!(pmf(&flat, &flat_right, &strings, &p).is_empty());
}

/// A right string that one left edge (the occluder's, 30 rasters) matches, with a stretch of
/// it taken by another left edge at 10 px more disparity (one the right camera cannot see):
/// the stretch goes back, since the occluder has edgels there at its own disparity. The same
/// right string running on past the occluder's end onto a third edge keeps that edge's
/// matches: nothing else has edgels on those rasters.
#[test]
fn a_right_string_belongs_to_the_left_edge_that_continues_along_it() {
    let occluder = edge(150.0, 10, 30, 0.0, true);
    let hidden = edge(160.0, 20, 10, 0.0, true);
    let beyond = edge(170.0, 40, 10, 0.0, true);
    let left: Vec<Edgel> = [occluder, hidden, beyond].concat();
    let right = edge(110.0, 10, 40, 0.0, true);
    let left_strings = strings_of(&[30, 10, 10]);
    let right_strings = strings_of(&[40]);
    let m = |l: u32, r: u32| Match {
        left: l,
        right: r,
        x: left[l as usize].x,
        y: left[l as usize].y,
        disparity: left[l as usize].x - right[r as usize].x,
        strength: 1.0,
    };
    // The occluder keeps rasters 10-19 and 30-39; the hidden edge took 20-29; the edge
    // beyond matched 40-49.
    let mut matches: Vec<Match> = (0..10).chain(20..30).map(|k| m(k, k)).collect();
    matches.extend((0..10).map(|k| m(30 + k, 10 + k)));
    matches.extend((0..10).map(|k| m(40 + k, 30 + k)));
    right_figural_continuity(&mut matches, (&left, &left_strings), (&right, &right_strings), 1.0);
    assert!(matches.iter().all(|m| !(30..40).contains(&m.left)), "the hidden edge's matches stand");
    assert_eq!(matches.iter().filter(|m| m.left < 30).count(), 20, "the occluder lost matches");
    assert_eq!(matches.iter().filter(|m| m.left >= 40).count(), 10, "the edge beyond lost matches");
}

/// An edge of the same contrast and direction, but with neither side's grey level like the
/// left edge's, is another edge: it is no candidate. Alike on one side (the other side a
/// different background, as behind a silhouette), it is.
#[test]
fn an_edge_matches_only_where_one_side_looks_the_same() {
    let left = edge(100.0, 10, 20, 0.2, true);
    let strings = strings_of(&[20]);
    let p = PmfParams { disparity_min: 20.0, disparity_max: 80.0, ..PmfParams::default() };
    let shifted =
        |sides: [f32; 2]| -> Vec<Edgel> { left.iter().map(|e| Edgel { x: e.x - 40.0, sides, ..*e }).collect() };
    assert!(pmf(&left, &shifted([60.0, 100.0]), &strings, &p).is_empty());
    assert_eq!(pmf(&left, &shifted([30.0, 40.0]), &strings, &p).len(), 20, "the bright side alike");
    assert_eq!(pmf(&left, &shifted([0.0, 12.0]), &strings, &p).len(), 20, "the dark side alike");
}

/// 20 edgels of an edge from `x`, brighter to the right, with `sides` and `contrast`.
fn step(x: f32, sides: [f32; 2], contrast: f32) -> Vec<Edgel> {
    edge(x, 10, 20, 0.2, true).into_iter().map(|e| Edgel { sides, contrast, ..e }).collect()
}

/// A strip one camera sees and the other does not, 5 px wide, grey 90 between a dark 40 and a
/// bright 140. Seen by the left camera (left of the bright surface, the nearer): the right
/// image's one edge is the bright surface's, 40 px off, and goes to the strip's bright edge
/// (whose contrast, a third of the right edge's, is excused), not its dark one (whose dark
/// side is alike and contrast passes: without the strip test it takes the match, 5 px
/// short). Seen by the right camera (right of the dark surface, now the nearer): the left
/// image's one edge goes to the strip's dark edge.
#[test]
fn a_strip_one_camera_sees_leaves_the_match_to_the_nearer_surfaces_edge() {
    let p = PmfParams { disparity_min: 20.0, disparity_max: 80.0, ..PmfParams::default() };
    let no_strip_test = PmfParams { one_view_strip_px: 0.0, one_view_strip_per_disparity: 0.0, ..p };
    let (dark_edge, bright_edge, whole) = STRIP_GREYS;
    strip_seen_by_the_left_camera((100.0, 5.0, 40.0), &p, &no_strip_test);

    let left = step(100.0, whole, 50.0);
    let right = [step(60.0, dark_edge, 15.0), step(65.0, bright_edge, 30.0)].concat();
    let matches = pmf(&left, &right, &strings_of(&[20]), &p);
    assert_eq!(matches.len(), 20);
    assert!(matches.iter().all(|m| m.right < 20 && (m.disparity - 40.0).abs() < 1e-3));
    let fooled = pmf(&left, &right, &strings_of(&[20]), &no_strip_test);
    assert!(!fooled.is_empty() && fooled.iter().all(|m| m.right >= 20 && (m.disparity - 35.0).abs() < 1e-3));
}

/// Nearer the cameras a face seen by one camera only is wider: a 13 px strip at 300 px of
/// disparity (wider than `one_view_strip_px`, within `one_view_strip_per_disparity` of it)
/// still leaves the match to the nearer surface's edge; with the width fixed at 10 px, the
/// strip's far edge takes it, 13 px of disparity short.
#[test]
fn a_wider_strip_nearer_the_cameras_is_still_seen_for_one() {
    let p = PmfParams { disparity_min: 200.0, disparity_max: 400.0, ..PmfParams::default() };
    let fixed_width = PmfParams { one_view_strip_per_disparity: 0.0, ..p };
    strip_seen_by_the_left_camera((400.0, 13.0, 300.0), &p, &fixed_width);
}

/// The greys of the strip tests: the strip's dark edge (40 | 90), its bright edge (90 | 140)
/// and the single edge the other camera sees (40 | 140).
const STRIP_GREYS: ([f32; 2], [f32; 2], [f32; 2]) = ([40.0, 90.0], [90.0, 140.0], [40.0, 140.0]);

/// A strip `width` px wide seen by the left camera only, its dark edge at `x`, the right
/// image's single edge at `disparity` from the strip's bright edge: with `p` every match
/// goes to the bright edge at `disparity`; with `fooled_by` the dark edge takes matches,
/// `width` short.
fn strip_seen_by_the_left_camera((x, width, disparity): (f32, f32, f32), p: &PmfParams, fooled_by: &PmfParams) {
    let (dark_edge, bright_edge, whole) = STRIP_GREYS;
    let strings = strings_of(&[20, 20]);
    let left = [step(x, dark_edge, 30.0), step(x + width, bright_edge, 15.0)].concat();
    let right = step(x + width - disparity, whole, 50.0);
    let matches = pmf(&left, &right, &strings, p);
    assert_eq!(matches.len(), 20);
    assert!(matches.iter().all(|m| m.left >= 20 && (m.disparity - disparity).abs() < 1e-3));
    let fooled = pmf(&left, &right, &strings, fooled_by);
    assert!(
        !fooled.is_empty() && fooled.iter().all(|m| m.left < 20 && (m.disparity - (disparity - width)).abs() < 1e-3)
    );
}

/// A crease on a glossy part: both faces a few grey levels brighter in the right image than
/// PMF's side tolerance allows. Refused while the pair's grey levels are taken to agree to
/// within the tolerance; a candidate where the pair's own scatter says they agree less well,
/// but only for a left edgel that no right edgel passes strictly.
#[test]
fn a_left_edgel_with_no_candidate_is_judged_again_within_the_pairs_scatter() {
    let p = PmfParams { disparity_min: 0.0, disparity_max: 100.0, ..PmfParams::default() };
    let left: Vec<Edgel> =
        edge(100.0, 10, 1, 0.2, true).into_iter().map(|e| Edgel { sides: [100.0, 200.0], ..e }).collect();
    let glossy = |x: f32, sides: [f32; 2]| Edgel { sides, ..edge(x, 10, 1, 0.2, true)[0] };
    let brighter = glossy(60.0, [106.0, 207.0]);
    let disparities = |right: &[Edgel], p: &PmfParams| {
        let (_, cands) = candidates(&left, right, p);
        cands.iter().map(|c| c.disparity).collect::<Vec<f32>>()
    };
    assert!(disparities(&[brighter], &p).is_empty());
    assert_eq!(refusal(&left[0], &[brighter], 40.0, 1.0, &p), Some(Refusal::Sides));
    let scattered = PmfParams { side_scatter: Scatter::uniform(2.5), ..p };
    assert_eq!(disparities(&[brighter], &scattered), vec![40.0]);
    assert_eq!(refusal(&left[0], &[brighter], 40.0, 1.0, &scattered), None);
    // Twice as far off is still another surface.
    assert!(disparities(&[glossy(60.0, [112.0, 214.0])], &scattered).is_empty());
    // A right edgel alike within the tolerance leaves no room for the looser test.
    let alike = glossy(70.0, [101.0, 198.0]);
    assert_eq!(disparities(&[brighter, alike], &scattered), vec![30.0]);
}
