//! Spatial parallelism as MARVIN had it: both images cut into horizontal slices (8 of ~64
//! rasters, adjacent slices sharing 2 rasters), each slice processor running Canny on its own
//! rasters of both images ([`canny_bands`]), then taking its slice pair through strings,
//! rectification, PMF, 2D and 3D lines on its own and in parallel, and a Joiner that merges the
//! per-slice descriptions where 2D lines continue across a seam, as if one processor had done
//! the whole image.
//!
//! Each slice processor also reads a halo of [`HALO`] rasters beyond its slice: PMF weighs a
//! match by its neighbours up to 20 px away, and an edgel near a seam judged without the
//! neighbours across it is judged differently from the whole image (measured: with the 2-raster
//! overlap alone, only 45% of 3D lines came out the same). The halo's edgels are its
//! neighbours' (passed on, as transputers pass boundary rows over their links, not found again:
//! `marvin bench vision`'s `sliced_canny` 9.9 -> 4.7 ms of processor time, `front_end` 15.6 ->
//! 11.1 ms, the latter alternated five times). What a slice reports from its halo is only
//! context: the Joiner keeps each edgel and match from the slice that owns its row.
//!
//! The right slice covers every right-image raster whose rectified row meets the rectified rows
//! of the left slice: the verged cameras' warp shifts and tilts rows, so it is taller than the
//! left slice and offset from it.

use super::canny::{CannyParams, CannyWorkspace, EdgeMap, Edgel};
use super::lines2d::Line2;
use super::lines3d::{Line3, Lines3dParams, complete_flat_lines, fit_lines3d, lines2d_split_at_depth_breaks};
use super::pipeline::{FrontEnd, MIN_STRING, Stopwatch};
use super::pmf::{Match, PmfParams, pmf, right_figural_continuity};
use super::rectify::{Rectification, Side};
use super::strings::{EdgeString, link_strings};
use super::workspace::Workspace;
use crate::image::GreyImage;
use mesh::StereoCalibration;
use rayon::prelude::*;
use std::ops::Range;
use std::time::Instant;

/// Rasters shared by adjacent slices.
pub const OVERLAP: usize = 2;
/// Rasters of context a slice processor reads beyond its slice (PMF's support radius and some).
pub const HALO: usize = 24;
/// Rasters of image above and below a slice that Canny reads for its smoothing and
/// non-maximum suppression (its edgels come only from the slice's own rows).
const CANNY_CONTEXT: usize = 6;

/// Where one slice lies in each image.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlicePlan {
    /// Left rasters this slice answers for (the Joiner keeps its edgels from these).
    pub owned: Range<usize>,
    /// Left rasters it processes: its own, the overlap into the next slice, and the halo.
    pub left: Range<usize>,
    /// Right rasters it processes.
    pub right: Range<usize>,
}

/// Cuts `height` rows into `n` slices and finds each one's right-image extent.
pub fn plan(height: usize, width: usize, n: usize, rect: &Rectification) -> Vec<SlicePlan> {
    let n = n.clamp(1, height.max(1));
    // Each right raster's band, found once for all slices: through a lens each corner is an
    // iterative undistortion, and per slice they were 8 x 512 x 4 of them, in series before
    // the slices start.
    let right_bands: Vec<(f64, f64)> =
        (0..height).map(|r| rectified_band(rect, Side::Right, &(r..r + 1), width)).collect();
    (0..n)
        .map(|k| {
            let owned = k * height / n..(k + 1) * height / n;
            let left = owned.start.saturating_sub(HALO)..(owned.end + OVERLAP + HALO).min(height);
            // The rectified rows the left slice spans (a rectified row is straight, so the
            // corners of the slice bound it).
            let band = rectified_band(rect, Side::Left, &left, width);
            let rows: Vec<usize> =
                (0..height).filter(|&r| right_bands[r].0 <= band.1 + 1.0 && right_bands[r].1 >= band.0 - 1.0).collect();
            let right = match (rows.first(), rows.last()) {
                (Some(&a), Some(&b)) => a..b + 1,
                _ => 0..0,
            };
            SlicePlan { owned, left, right }
        })
        .collect()
}

/// Lowest and highest rectified row that rows `rows` of one camera's image map to.
fn rectified_band(rect: &Rectification, side: Side, rows: &Range<usize>, width: usize) -> (f64, f64) {
    let (top, bottom) = (rows.start as f64 - 0.5, rows.end as f64 - 0.5);
    let corners = [(-0.5, top), (width as f64 - 0.5, top), (-0.5, bottom), (width as f64 - 0.5, bottom)];
    corners.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &(x, y)| {
        let (_, ry) = rect.to_rectified(side, x, y);
        (lo.min(ry), hi.max(ry))
    })
}

/// What a slice processor keeps from slice to slice: Canny's buffers and the two edge maps
/// (fresh maps cost page faults every time).
#[derive(Default)]
struct SliceBuffers {
    canny: CannyWorkspace,
    left: EdgeMap,
    right: EdgeMap,
}

thread_local! {
    /// One set of buffers per worker thread. Borrowed only where no rayon call can run another
    /// slice on this thread meanwhile.
    static SLICE_BUFFERS: std::cell::RefCell<SliceBuffers> = Default::default();
}

/// Canny's edgels from rows `rows` of `img`, found with a little context around them, into
/// `out` (sub-image pixels); returns the sub-image's first row.
fn canny_rows(
    ws: &mut CannyWorkspace,
    img: &GreyImage,
    rows: &Range<usize>,
    params: &CannyParams,
    out: &mut EdgeMap,
) -> usize {
    let from = rows.start.saturating_sub(CANNY_CONTEXT);
    let to = (rows.end + CANNY_CONTEXT).min(img.height);
    let sub = GreyImage::new(img.width, to - from, img.pixels[from * img.width..to * img.width].to_vec())
        .expect("rows are within the image");
    ws.run(&sub, params, out);
    out.keep_rows(&((rows.start - from)..(rows.end - from)));
    from
}

/// What one slice pair found; edgel indices are the slice's own.
#[derive(Debug, Clone)]
pub struct SliceResult {
    pub plan: SlicePlan,
    /// Left edgels in whole-image pixels, and rectified.
    pub left: Vec<Edgel>,
    pub left_rect: Vec<Edgel>,
    /// Whole-image pixel (row-major index) of each left edgel, and the image width.
    pub left_pixel: Vec<usize>,
    pub width: usize,
    pub right: Vec<Edgel>,
    /// Whole-image pixel of each right edgel (right slices overlap a lot; the Joiner dedupes).
    pub right_pixel: Vec<usize>,
    pub strings: Vec<EdgeString>,
    pub matches: Vec<Match>,
    pub lines2d: Vec<Line2>,
    pub lines3d: Vec<Line3>,
    /// Time each stage took on this slice, milliseconds.
    pub timings_ms: Vec<(&'static str, f64)>,
}

fn shift(edgels: &[Edgel], dy: usize) -> Vec<Edgel> {
    edgels.iter().map(|e| Edgel { y: e.y + dy as f32, ..*e }).collect()
}

/// One image's Canny edgels from the rows one slice processor answers for (found with
/// [`CANNY_CONTEXT`] rows of image beyond them), in whole-image pixels and rows.
pub struct Band {
    rows: Range<usize>,
    edgels: Vec<Edgel>,
    /// Whole-image pixel (row-major index) of each edgel.
    pixel: Vec<usize>,
    /// Milliseconds its Canny took.
    ms: f64,
}

/// Canny on each of `bands`' rows of `img`, in parallel: each slice processor's own rows,
/// once. A slice's halo is then made up of its neighbours' bands ([`halo_map`]), as MARVIN's
/// transputers would pass boundary rows over their links, rather than each slice smoothing its
/// halo again (the halos and the taller right slices had each image smoothed ~2.9 times over).
pub fn canny_bands(img: &GreyImage, bands: &[Range<usize>], params: &CannyParams) -> Vec<Band> {
    bands
        .par_iter()
        .map(|rows| {
            let clock = Instant::now();
            SLICE_BUFFERS.with(|buffers| {
                let SliceBuffers { canny, left: map, .. } = &mut *buffers.borrow_mut();
                let from = canny_rows(canny, img, rows, params, map);
                Band {
                    rows: rows.clone(),
                    edgels: shift(&map.edgels, from),
                    pixel: map.pixel.iter().map(|&p| p as usize + from * img.width).collect(),
                    ms: clock.elapsed().as_secs_f64() * 1e3,
                }
            })
        })
        .collect()
}

/// The edge map of rows `rows` (numbered from `rows.start`, edgels' rows likewise) made up of
/// the `bands` that meet them, in row order as Canny gives them.
fn halo_map(bands: &[Band], rows: &Range<usize>, width: usize, out: &mut EdgeMap) {
    out.reset(width, rows.len());
    let dy = rows.start as f32;
    for band in bands.iter().filter(|b| b.rows.start < rows.end && b.rows.end > rows.start) {
        for (e, &p) in band.edgels.iter().zip(&band.pixel) {
            if rows.contains(&(p / width)) {
                out.push(p - rows.start * width, Edgel { y: e.y - dy, ..*e });
            }
        }
    }
}

/// Stages 2-6 on one slice pair, with the bands' edgels (stage 1, [`canny_bands`]).
pub fn run_slice(
    (left_bands, right_bands): (&[Band], &[Band]),
    width: usize,
    plan: &SlicePlan,
    (rect, workspace): (&Rectification, &Workspace),
    own_band: usize,
) -> SliceResult {
    let mut watch = Stopwatch::start();
    let (strings, left_edgels, left_pixel, right_edgels, right_pixel) = SLICE_BUFFERS.with(|buffers| {
        let SliceBuffers { left: lmap, right: rmap, .. } = &mut *buffers.borrow_mut();
        let (lfrom, rfrom) = (plan.left.start, plan.right.start);
        halo_map(left_bands, &plan.left, width, lmap);
        halo_map(right_bands, &plan.right, width, rmap);
        // Its own bands' Canny, then the halos' making up.
        watch.laps.push(("canny", left_bands[own_band].ms + right_bands[own_band].ms));
        watch.lap("halo");
        let strings = link_strings(lmap, MIN_STRING);
        watch.lap("strings");
        let left_pixel = lmap.pixel.iter().map(|&p| p as usize + lfrom * width).collect();
        let right_pixel = rmap.pixel.iter().map(|&p| p as usize + rfrom * width).collect();
        (strings, shift(&lmap.edgels, lfrom), left_pixel, shift(&rmap.edgels, rfrom), right_pixel)
    });
    let left_rect = rect.rectify_edgels(Side::Left, &left_edgels);
    let right_rect = rect.rectify_edgels(Side::Right, &right_edgels);
    watch.lap("rectify");
    let (disparity_min, disparity_max, floor) = workspace.search(rect);
    let pmf_params = PmfParams { disparity_min, disparity_max, floor, ..PmfParams::default() };
    let matches = pmf(&left_rect, &right_rect, &strings, &pmf_params);
    watch.lap("pmf");
    let lines2d = lines2d_split_at_depth_breaks(&left_rect, &strings, &matches);
    watch.lap("geom2d");
    let p3 = Lines3dParams::default();
    let mut lines3d = fit_lines3d(&lines2d, &strings, &left_rect, &matches, rect, &p3);
    complete_flat_lines(&lines2d, &strings, &mut lines3d, rect, &p3, 6);
    watch.lap("geom3d");
    SliceResult {
        plan: plan.clone(),
        left: left_edgels,
        left_rect,
        left_pixel,
        width,
        right: right_edgels,
        right_pixel,
        strings,
        matches,
        lines2d,
        lines3d,
        timings_ms: watch.laps,
    }
}

/// The front end with the images cut into `n` slices processed in parallel, then joined.
pub fn run_sliced(
    left: &GreyImage,
    right: &GreyImage,
    calib: &StereoCalibration,
    workspace: &Workspace,
    params: &CannyParams,
    n: usize,
) -> FrontEnd {
    let clock = Instant::now();
    let rect = Rectification::new(calib);
    let plans = plan(left.height, left.width, n, &rect);
    let owned: Vec<Range<usize>> = plans.iter().map(|p| p.owned.clone()).collect();
    // Each camera's thresholds above its own noise, the same in every slice.
    let (left_params, right_params) = (params.for_image(left), params.for_image(right));
    let (left_bands, right_bands) =
        rayon::join(|| canny_bands(left, &owned, &left_params), || canny_bands(right, &owned, &right_params));
    let slices: Vec<SliceResult> = plans
        .par_iter()
        .enumerate()
        .map(|(k, p)| run_slice((&left_bands, &right_bands), left.width, p, (&rect, workspace), k))
        .collect();
    let slices_ms = clock.elapsed().as_secs_f64() * 1e3;
    let clock = Instant::now();
    let mut fe = join(&slices, rect.clone(), (left.width, left.height), &workspace.search(&rect));
    // Per stage, the processor time summed over the slices (they overlap in wall time); then
    // the wall time of all slices and of the Joiner.
    for (name, _) in &slices[0].timings_ms {
        let total = slices.iter().flat_map(|s| &s.timings_ms).filter(|(n, _)| n == name).map(|(_, ms)| ms).sum();
        fe.timings_ms.push((name, total));
    }
    fe.timings_ms.push(("slices", slices_ms));
    fe.timings_ms.push(("join", clock.elapsed().as_secs_f64() * 1e3));
    if let Some(table) = &workspace.table {
        fe.set_apart_soft_lines(table);
    }
    fe
}

/// The Joiner. Edgels and matches come from the slice that owns their row. A string that lay
/// wholly in one slice's own rows keeps that slice's 2D and 3D lines as they are; edgels of
/// strings that crossed a seam are linked again across it, and their 2D and 3D lines fitted
/// afresh from the joined strings and the owners' matches, as one processor would have.
pub fn join(
    slices: &[SliceResult],
    rect: Rectification,
    (width, height): (usize, usize),
    search: &super::flat_lines::Search,
) -> FrontEnd {
    let mut fe = FrontEnd::empty(Some(rect.clone()));
    fe.left = EdgeMap::new(width, height);
    fe.right = EdgeMap::new(width, height);
    let mut ids_of: Vec<Vec<Option<u32>>> = Vec::with_capacity(slices.len());
    for s in slices {
        let mut ids = vec![None; s.left.len()];
        for (i, e) in s.left.iter().enumerate() {
            if owns(s, i) {
                ids[i] = Some(fe.left.edgels.len() as u32);
                fe.left.push(s.left_pixel[i], *e);
                fe.left_rectified.push(s.left_rect[i]);
            }
        }
        let mut right_ids = Vec::with_capacity(s.right.len());
        for (e, &p) in s.right.iter().zip(&s.right_pixel) {
            if fe.right.at_pixel[p] == super::canny::NO_EDGEL {
                fe.right.push(p, *e);
            }
            right_ids.push(fe.right.at_pixel[p]);
        }
        fe.matches.extend(
            s.matches
                .iter()
                .filter_map(|m| Some(Match { left: ids[m.left as usize]?, right: right_ids[m.right as usize], ..*m })),
        );
        ids_of.push(ids);
    }
    // Link the owned edgels over the whole image: across the seams, strings come out as one
    // processor would have linked them.
    fe.left_strings = link_strings(&fe.left, MIN_STRING);
    // Continuity along the right image's strings is judged on whole strings, as one processor
    // would (a slice sees a right string cut at its rows); the strings whose matches it
    // changes have their lines fitted afresh below.
    let (dropped, right_strings) = right_continuity_over_the_image(&mut fe, &rect);
    // A string some slice saw whole, in the same order, keeps that slice's lines; the others
    // (those that crossed a seam) have their 2D and 3D lines fitted afresh.
    let mut seen_whole: std::collections::HashMap<Vec<u32>, (usize, usize)> = Default::default();
    for (k, (s, ids)) in slices.iter().zip(&ids_of).enumerate() {
        for (si, st) in s.strings.iter().enumerate() {
            if let Some(global) = st.edgels.iter().map(|&i| ids[i as usize]).collect::<Option<Vec<u32>>>() {
                seen_whole.insert(global, (k, si));
            }
        }
    }
    let mut inlier = vec![false; fe.left.edgels.len()];
    let mut refit = Vec::new();
    for (gi, st) in fe.left_strings.iter().enumerate() {
        let whole = seen_whole.get(&st.edgels).filter(|_| !st.edgels.iter().any(|&i| dropped[i as usize]));
        let Some(&(k, si)) = whole else {
            refit.push(gi);
            continue;
        };
        let (s, ids) = (&slices[k], &ids_of[k]);
        for (li, line) in s.lines2d.iter().enumerate().filter(|(_, l)| l.string as usize == si) {
            let line2 = fe.lines2d.len() as u32;
            fe.lines2d.push(Line2 { string: gi as u32, ..line.clone() });
            if let Some(l3) = s.lines3d.iter().find(|l3| l3.line2 as usize == li) {
                let inliers: Vec<u32> = l3.inliers.iter().filter_map(|&i| ids[i as usize]).collect();
                for &g in &inliers {
                    inlier[g as usize] = true;
                }
                fe.lines3d.push(Line3 { line2, inliers, ..l3.clone() });
            }
        }
    }
    let p3 = Lines3dParams::default();
    let to_refit: Vec<EdgeString> = refit.iter().map(|&gi| fe.left_strings[gi].clone()).collect();
    let mut lines = lines2d_split_at_depth_breaks(&fe.left_rectified, &to_refit, &fe.matches);
    let mut lines3d = fit_lines3d(&lines, &to_refit, &fe.left_rectified, &fe.matches, &rect, &p3);
    let line_base = fe.lines2d.len() as u32;
    for l in &mut lines {
        l.string = refit[l.string as usize] as u32;
    }
    for l3 in &mut lines3d {
        l3.line2 += line_base;
        for &g in &l3.inliers {
            inlier[g as usize] = true;
        }
    }
    fe.lines2d.extend(lines);
    fe.lines3d.extend(lines3d);
    // Flat lines take their 3D ends from the lines meeting them, whichever slice those came from.
    complete_flat_lines(&fe.lines2d, &fe.left_strings, &mut fe.lines3d, &rect, &p3, 6);
    // And lines along the rasters matched whole, the right image's strings linked over it all
    // (its lines may cross the seams).
    let images = super::flat_lines::Images {
        lines2d: &fe.lines2d,
        left_strings: &fe.left_strings,
        left_rectified: &fe.left_rectified,
        right_strings: &right_strings,
        right_rectified: &fe.right_rectified,
    };
    super::flat_lines::match_flat_lines(&images, &rect, search, &mut fe.lines3d);
    // As the whole-image front end does: vouch only for matches on 3D lines.
    fe.matches.retain(|m| inlier[m.left as usize]);
    fe
}

/// [`right_figural_continuity`] over the joined matches (right edgels indexed in the whole
/// right image); which left edgels lost their match, and the right image's strings.
fn right_continuity_over_the_image(fe: &mut FrontEnd, rect: &Rectification) -> (Vec<bool>, Vec<EdgeString>) {
    let right_rect = rect.rectify_edgels(Side::Right, &fe.right.edgels);
    let right_strings = link_strings(&fe.right, MIN_STRING);
    let mut dropped = vec![false; fe.left.edgels.len()];
    for m in &fe.matches {
        dropped[m.left as usize] = true;
    }
    right_figural_continuity(
        &mut fe.matches,
        (&fe.left_rectified, &fe.left_strings),
        (&right_rect, &right_strings),
        PmfParams::default().continuity_step,
    );
    for m in &fe.matches {
        dropped[m.left as usize] = false;
    }
    fe.right_rectified = right_rect;
    (dropped, right_strings)
}

/// Whether slice `s` owns its left edgel `i` (the edgel's row is one of the slice's own).
fn owns(s: &SliceResult, i: usize) -> bool {
    s.plan.owned.contains(&(s.left_pixel[i] / s.width))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::rectify::tests::verged_pair;
    use nalgebra::Point3;

    #[test]
    fn slices_cover_the_image_sharing_two_rasters() {
        let rect = Rectification::new(&verged_pair());
        let plans = plan(512, 512, 8, &rect);
        assert_eq!(plans.len(), 8);
        assert_eq!(plans[0].owned.start, 0);
        assert_eq!(plans[7].owned.end, 512);
        for w in plans.windows(2) {
            assert_eq!(w[0].owned.end, w[1].owned.start);
            assert!(w[0].left.end >= w[1].owned.start + OVERLAP);
        }
        assert!(plans.iter().all(|p| (p.owned.end - p.owned.start) == 64));
    }

    #[test]
    fn a_right_slice_holds_what_its_left_slice_sees() {
        // Points on the table and above it, seen in a left slice, must fall in its right slice.
        let calib = verged_pair();
        let rect = Rectification::new(&calib);
        let plans = plan(512, 512, 8, &rect);
        for ix in -10..=10 {
            for iy in -10..=10 {
                for z in [0.0, 0.1] {
                    let p = Point3::new(ix as f64 * 0.02, iy as f64 * 0.02, z);
                    let (Some(l), Some(r)) = (calib.left.project_world(&p), calib.right.project_world(&p)) else {
                        continue;
                    };
                    if !(0.0..511.5).contains(&l.y)
                        || !(0.0..511.5).contains(&r.y)
                        || !(0.0..511.5).contains(&l.x)
                        || !(0.0..511.5).contains(&r.x)
                    {
                        continue;
                    }
                    let row = l.y.round() as usize;
                    let slice = plans.iter().find(|s| s.owned.contains(&row)).unwrap();
                    assert!(
                        slice.right.contains(&(r.y.round() as usize)),
                        "point {p} at left row {row}, right row {}, slice {slice:?}",
                        r.y
                    );
                }
            }
        }
    }
}
