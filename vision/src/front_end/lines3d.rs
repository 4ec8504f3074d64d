//! 3D geometry: along each 2D line (fitted in rectified left coordinates), the matched edgels
//! give (arc length, disparity) pairs; a robust straight-line fit of disparity against arc
//! length, projected through the calibration at the line's ends, gives a 3D segment in the
//! `cam` frame with the depth uncertainty of each end. A 2D line along which the disparity
//! breaks (two edges at different depths that run on in one straight image line) is first
//! split at the break ([`split_at_depth_breaks`]).

use super::lines2d::Line2;
use super::pmf::Match;
use super::rectify::Rectification;
use super::strings::EdgeString;
use nalgebra::Point3;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Lines3dParams {
    /// Fewest matched edgels on a line.
    pub min_matches: usize,
    /// Matched edgels must cover at least this fraction of the line.
    pub min_span: f32,
    /// Lines within this angle (radians) of the rasters are dropped: their disparity is unreliable.
    pub min_angle_to_raster: f32,
    /// Matches farther than this from the disparity fit (pixels) are dropped as outliers.
    pub max_residual: f32,
    /// Largest plausible disparity change per pixel along a line.
    pub max_slope: f32,
}

impl Default for Lines3dParams {
    fn default() -> Self {
        Lines3dParams { min_matches: 5, min_span: 0.3, min_angle_to_raster: 0.25, max_residual: 1.0, max_slope: 1.5 }
    }
}

/// A match the front end vouches for lies within this many pixels of disparity of its 3D line's
/// fit (the fit itself keeps matches within `max_residual`, 1 px). Of the matches between half
/// a pixel and a pixel off their line, two thirds are more than half a pixel off the true disparity
/// (`widgets.toml` seeds 1-50, against 4% of all matches). Vouching only for those within
/// 0.5 px drops 0.8% of the matches and leaves the lines as they were: on seeds 1-50 / 101-150
/// (`marvin eval vision worlds/widgets.toml --scenes 50`) within 0.5 px 95.96 / 95.75% ->
/// 96.48 / 96.25%, coverage the same; 0.35 px gave 96.98 / 96.76% for 2.2% of the matches,
/// 0.25 px 97.34 / 97.10% for 4.8%. The matcher reads the matches' depths edgel by edgel
/// (`matcher::depths`): `eval locate` gave the same reports on widgets 1-120, dense and side
/// light 1-60.
pub const VOUCH_PX: f64 = 0.5;

/// A 3D line segment in the `cam` frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Line3 {
    pub a: [f64; 3],
    pub b: [f64; 3],
    /// Standard deviation of each end's depth, metres (from the disparity fit's residuals).
    pub sigma_a: f64,
    pub sigma_b: f64,
    /// Disparity at the 2D line's start and end (rectified pixels).
    pub disparity_start: f64,
    pub disparity_end: f64,
    /// The 2D line it came from (index into the 2D lines) and how many matches carried it
    /// (0 for a line along the rasters, see [`Depths`]).
    pub line2: u32,
    pub matches: u32,
    /// Where its depths came from.
    pub depths: Depths,
    /// The left edgels whose matches agree with the fit (the inliers).
    #[serde(skip)]
    pub inliers: Vec<u32>,
}

/// Where a 3D line's depths came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Depths {
    /// PMF's matches along it, fitted ([`fit_lines3d`]).
    Matches,
    /// The 3D lines meeting its ends ([`complete_flat_lines`]).
    Corners,
    /// The right image's line through the same rows ([`super::flat_lines`]).
    WholeLine,
}

impl Line3 {
    pub fn start(&self) -> Point3<f64> {
        Point3::from(self.a)
    }
    pub fn end(&self) -> Point3<f64> {
        Point3::from(self.b)
    }
}

/// Least-squares `d = alpha + beta s` with the residual variance; `None` if degenerate.
fn linear_fit(points: &[(f64, f64)]) -> Option<(f64, f64, f64, f64, f64)> {
    let n = points.len() as f64;
    let (ms, md) = points.iter().fold((0.0, 0.0), |(a, b), &(s, d)| (a + s, b + d));
    let (ms, md) = (ms / n, md / n);
    let sss: f64 = points.iter().map(|&(s, _)| (s - ms).powi(2)).sum();
    if sss < 1e-9 || points.len() < 3 {
        return None;
    }
    let beta = points.iter().map(|&(s, d)| (s - ms) * (d - md)).sum::<f64>() / sss;
    let alpha = md - beta * ms;
    let var = points.iter().map(|&(s, d)| (d - alpha - beta * s).powi(2)).sum::<f64>() / (n - 2.0).max(1.0);
    Some((alpha, beta, var, ms, sss))
}

/// The matched edgels along a 2D line as (arc length from its start, disparity, edgel), in
/// string order; `None` for a line too near the rasters (or too short) to carry disparities.
fn disparities_along(
    line: &Line2,
    strings: &[EdgeString],
    left_rect: &[super::canny::Edgel],
    disparity: &[f64],
    p: &Lines3dParams,
) -> Option<Vec<(f64, f64, u32)>> {
    let dir = line.direction();
    if (dir[1].abs() as f64) < (p.min_angle_to_raster as f64).sin() || line.length() < 1.0 {
        return None;
    }
    let string = &strings[line.string as usize].edgels;
    let along = |i: u32| {
        let e = &left_rect[i as usize];
        ((e.x - line.start[0]) * dir[0] + (e.y - line.start[1]) * dir[1]) as f64
    };
    Some(
        string[line.first as usize..=line.last as usize]
            .iter()
            .filter(|&&i| !disparity[i as usize].is_nan())
            .map(|&i| (along(i), disparity[i as usize], i))
            .collect(),
    )
}

/// A line's fit must leave at least this share of its matches within `max_residual` for it
/// not to be looked at for a break in depth.
const BREAK_INLIERS: f64 = 0.85;
/// Each side of a break must fit a straight line this well (rms, pixels of disparity)...
const BREAK_RMS: f64 = 0.35;
/// ...and the break must leave at least this much more of the matches on a fit.
const BREAK_GAIN: f64 = 1.25;

/// 2D lines split where the disparity along them breaks: two edges at different depths that
/// happen to run on in one straight line in the left image (a standing part's side edge
/// continued by the edge of a part behind it) are two 3D lines, and a single straight fit of
/// disparity against arc length keeps neither. Where one fit leaves under [`BREAK_INLIERS`] of
/// the matches, the break that fits both sides best (each side by least squares, over every
/// split of the matches in string order that leaves `min_matches` either side) is taken if
/// both sides fit within [`BREAK_RMS`] and between them keep [`BREAK_GAIN`] times the matches
/// the single fit did; each side is then fitted as a 2D line of its own.
pub fn split_at_depth_breaks(
    lines: Vec<Line2>,
    strings: &[EdgeString],
    left_rect: &[super::canny::Edgel],
    matches: &[Match],
    p: &Lines3dParams,
    p2: &super::lines2d::Lines2dParams,
) -> Vec<Line2> {
    let mut disparity = vec![f64::NAN; left_rect.len()];
    for m in matches {
        disparity[m.left as usize] = m.disparity as f64;
    }
    let mut out = Vec::with_capacity(lines.len());
    for line in lines {
        let pieces = disparities_along(&line, strings, left_rect, &disparity, p)
            .and_then(|points| depth_break(&points, p))
            .and_then(|last_before| split_line(&line, strings, left_rect, last_before, p2));
        match pieces {
            Some(pieces) => out.extend(pieces),
            None => out.push(line),
        }
    }
    out
}

/// The 2D lines of `strings` (default parameters), split where the disparity of `matches`
/// along them breaks: what the whole-image and sliced front ends and the join's refit all run.
pub fn lines2d_split_at_depth_breaks(
    left_rect: &[super::canny::Edgel],
    strings: &[EdgeString],
    matches: &[Match],
) -> Vec<Line2> {
    let p2 = super::lines2d::Lines2dParams::default();
    let lines = super::lines2d::fit_lines(left_rect, strings, &p2);
    split_at_depth_breaks(lines, strings, left_rect, matches, &Lines3dParams::default(), &p2)
}

/// How many of `points` lie within `max_residual` of a straight fit (two passes, as
/// [`fit_lines3d`] fits).
fn inliers_of_one_fit(points: &[(f64, f64)], max_residual: f64) -> usize {
    let mut kept: Vec<(f64, f64)> = points.to_vec();
    for _ in 0..2 {
        let Some((alpha, beta, ..)) = linear_fit(&kept) else { return 0 };
        kept = points.iter().copied().filter(|&(s, d)| (d - alpha - beta * s).abs() <= max_residual).collect();
    }
    kept.len()
}

/// The edgel after which the disparity along a line breaks, if it does (see
/// [`split_at_depth_breaks`]).
fn depth_break(points: &[(f64, f64, u32)], p: &Lines3dParams) -> Option<u32> {
    let n = points.len();
    if n < 2 * p.min_matches {
        return None;
    }
    let pairs: Vec<(f64, f64)> = points.iter().map(|&(s, d, _)| (s, d)).collect();
    let one = inliers_of_one_fit(&pairs, p.max_residual as f64);
    if one as f64 >= BREAK_INLIERS * n as f64 {
        return None;
    }
    let sse = |pts: &[(f64, f64)]| linear_fit(pts).map(|(_, _, var, ..)| var * (pts.len() as f64 - 2.0));
    let (k, _) = (p.min_matches..=n - p.min_matches)
        .filter_map(|k| Some((k, sse(&pairs[..k])? + sse(&pairs[k..])?)))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let rms = |pts: &[(f64, f64)]| linear_fit(pts).map_or(f64::INFINITY, |(_, _, var, ..)| var.sqrt());
    let both =
        inliers_of_one_fit(&pairs[..k], p.max_residual as f64) + inliers_of_one_fit(&pairs[k..], p.max_residual as f64);
    (rms(&pairs[..k]) <= BREAK_RMS && rms(&pairs[k..]) <= BREAK_RMS && both as f64 >= BREAK_GAIN * one as f64)
        .then_some(points[k - 1].2)
}

/// `line` cut after its string's edgel `last_before`, each side fitted as a 2D line of its own
/// (a side too short to be one is left out).
fn split_line(
    line: &Line2,
    strings: &[EdgeString],
    left_rect: &[super::canny::Edgel],
    last_before: u32,
    p2: &super::lines2d::Lines2dParams,
) -> Option<Vec<Line2>> {
    let string = &strings[line.string as usize].edgels;
    let cut =
        string[line.first as usize..=line.last as usize].iter().position(|&i| i == last_before)? + line.first as usize;
    let pts: Vec<[f32; 2]> = string.iter().map(|&i| [left_rect[i as usize].x, left_rect[i as usize].y]).collect();
    Some(
        [(line.first as usize, cut), (cut + 1, line.last as usize)]
            .into_iter()
            .filter(|(a, b)| a < b)
            .filter_map(|(a, b)| super::lines2d::fit_piece(&pts, a, b, line.string, p2))
            .collect(),
    )
}

/// 3D lines from 2D lines (fitted on the rectified left edgels `left_rect`) and PMF matches.
pub fn fit_lines3d(
    lines: &[Line2],
    strings: &[EdgeString],
    left_rect: &[super::canny::Edgel],
    matches: &[Match],
    rect: &Rectification,
    p: &Lines3dParams,
) -> Vec<Line3> {
    let mut disparity = vec![f64::NAN; left_rect.len()];
    for m in matches {
        disparity[m.left as usize] = m.disparity as f64;
    }
    let mut out = Vec::new();
    for (li, line) in lines.iter().enumerate() {
        let len = line.length() as f64;
        let dir = line.direction();
        let Some(mut points) = disparities_along(line, strings, left_rect, &disparity, p) else {
            continue;
        };
        let pairs = |pts: &[(f64, f64, u32)]| pts.iter().map(|&(s, d, _)| (s, d)).collect::<Vec<_>>();
        // Two passes: fit, drop outliers, fit again.
        let mut fit = None;
        for _ in 0..2 {
            if points.len() < p.min_matches {
                break;
            }
            fit = linear_fit(&pairs(&points));
            let Some((alpha, beta, ..)) = fit else { break };
            points.retain(|&(s, d, _)| (d - alpha - beta * s).abs() <= p.max_residual as f64);
        }
        if points.len() < p.min_matches {
            continue;
        }
        let Some((alpha, beta, var, ms, sss)) = linear_fit(&pairs(&points)).or(fit) else {
            continue;
        };
        let (lo, hi) = points.iter().fold((f64::MAX, f64::MIN), |(a, b), &(s, ..)| (a.min(s), b.max(s)));
        if (hi - lo) < p.min_span as f64 * len || beta.abs() > p.max_slope as f64 {
            continue;
        }
        let n = points.len() as f64;
        let end = |s: f64| {
            let d = alpha + beta * s;
            let sigma_d = (var * (1.0 / n + (s - ms).powi(2) / sss)).sqrt();
            let (x, y) = (line.start[0] as f64 + s * dir[0] as f64, line.start[1] as f64 + s * dir[1] as f64);
            let point = rect.triangulate(x, y, d);
            let depth = rect.f * rect.baseline / d;
            (point, depth * depth * sigma_d / (rect.f * rect.baseline))
        };
        let ((a, sigma_a), (b, sigma_b)) = (end(0.0), end(len));
        let (disparity_start, disparity_end) = (alpha, alpha + beta * len);
        if !(a.coords.iter().chain(b.coords.iter()).all(|c| c.is_finite())) {
            continue;
        }
        out.push(Line3 {
            a: [a.x, a.y, a.z],
            b: [b.x, b.y, b.z],
            sigma_a,
            sigma_b,
            disparity_start,
            disparity_end,
            line2: li as u32,
            matches: points.len() as u32,
            depths: Depths::Matches,
            inliers: points
                .iter()
                .filter(|&&(s, d, _)| (d - alpha - beta * s).abs() <= VOUCH_PX)
                .map(|&(.., i)| i)
                .collect(),
        });
    }
    out
}

/// How near (pixels) the ends of two lines must be in the image to be taken for one corner.
const CORNER_PX: f32 = 3.0;

/// The disparity a 3D line's fit gives at image point `q` (projected onto its 2D line).
fn disparity_near(l3: &Line3, l2: &Line2, q: [f32; 2]) -> f64 {
    let dir = l2.direction();
    let s = ((q[0] - l2.start[0]) * dir[0] + (q[1] - l2.start[1]) * dir[1]) as f64;
    let len = l2.length().max(1e-6) as f64;
    l3.disparity_start + (l3.disparity_end - l3.disparity_start) * s / len
}

/// Lines too near the rasters to carry disparities of their own, completed from the 3D lines
/// that meet them at both ends along their string (figural continuity round the corners): a
/// straight image line between two 3D corner points is a straight 3D line between them.
/// `max_gap` is how many string edgels may lie between a line and its neighbour.
pub fn complete_flat_lines(
    lines: &[Line2],
    strings: &[EdgeString],
    lines3d: &mut Vec<Line3>,
    rect: &Rectification,
    p: &Lines3dParams,
    max_gap: u32,
) {
    let mut by_line: Vec<Option<usize>> = vec![None; lines.len()];
    for (k, l) in lines3d.iter().enumerate() {
        by_line[l.line2 as usize] = Some(k);
    }
    let mut added = Vec::new();
    for (li, line) in lines.iter().enumerate() {
        if by_line[li].is_some() || line.length() < 10.0 {
            continue;
        }
        let string_len = strings[line.string as usize].edgels.len() as u32;
        // Neighbours along the same string, by the gap between their edgel runs (wrapping round
        // a closed string).
        let gap = |from: u32, to: u32| (to + string_len - from) % string_len;
        let neighbour = |before: bool| {
            lines.iter().enumerate().filter(|(k, o)| *k != li && o.string == line.string).find_map(|(k, o)| {
                let g = if before { gap(o.last, line.first) } else { gap(line.last, o.first) };
                (g <= max_gap).then_some(by_line[k]).flatten().map(|i3| (k, i3))
            })
        };
        // Or, where the string broke at the corner, a 3D line ending right there in the image.
        let meeting = |q: [f32; 2]| {
            lines.iter().enumerate().filter(|(k, _)| *k != li).find_map(|(k, o)| {
                let near = |e: [f32; 2]| (e[0] - q[0]).powi(2) + (e[1] - q[1]).powi(2) <= CORNER_PX * CORNER_PX;
                let turns = {
                    let (a, b) = (o.direction(), line.direction());
                    (a[0] * b[1] - a[1] * b[0]).abs() > 0.3
                };
                ((near(o.start) || near(o.end)) && turns).then_some(by_line[k]).flatten().map(|i3| (k, i3))
            })
        };
        let (Some((pk, p3)), Some((nk, n3))) =
            (neighbour(true).or_else(|| meeting(line.start)), neighbour(false).or_else(|| meeting(line.end)))
        else {
            continue;
        };
        let d_start = disparity_near(&lines3d[p3], &lines[pk], line.start);
        let d_end = disparity_near(&lines3d[n3], &lines[nk], line.end);
        if d_start <= 0.0 || d_end <= 0.0 || (d_end - d_start).abs() > p.max_slope as f64 * line.length() as f64 {
            continue;
        }
        let a = rect.triangulate(line.start[0] as f64, line.start[1] as f64, d_start);
        let b = rect.triangulate(line.end[0] as f64, line.end[1] as f64, d_end);
        added.push(Line3 {
            a: [a.x, a.y, a.z],
            b: [b.x, b.y, b.z],
            sigma_a: lines3d[p3].sigma_a.max(lines3d[p3].sigma_b),
            sigma_b: lines3d[n3].sigma_a.max(lines3d[n3].sigma_b),
            disparity_start: d_start,
            disparity_end: d_end,
            line2: li as u32,
            matches: 0,
            depths: Depths::Corners,
            inliers: Vec::new(),
        });
    }
    lines3d.extend(added);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::canny::Edgel;
    use crate::front_end::lines2d::{Lines2dParams, fit_lines};

    /// A straight, steep string of 80 rectified left edgels and a match on each, its disparity
    /// `disparity(k)` at edgel `k`.
    fn string_with(disparity: impl Fn(usize) -> f32) -> (Vec<Edgel>, Vec<EdgeString>, Vec<Match>) {
        let edgels: Vec<Edgel> = (0..80)
            .map(|k| Edgel {
                x: 100.0 + 0.1 * k as f32,
                y: k as f32,
                orientation: 0.0,
                contrast: 20.0,
                sides: [0.0; 2],
            })
            .collect();
        let matches = edgels
            .iter()
            .enumerate()
            .map(|(k, e)| Match {
                left: k as u32,
                right: k as u32,
                x: e.x,
                y: e.y,
                disparity: disparity(k),
                strength: 1.0,
            })
            .collect();
        (edgels, vec![EdgeString { edgels: (0..80).collect() }], matches)
    }

    fn split(edgels: &[Edgel], strings: &[EdgeString], matches: &[Match]) -> Vec<Line2> {
        let p2 = Lines2dParams::default();
        let lines = fit_lines(edgels, strings, &p2);
        assert_eq!(lines.len(), 1, "the string is one straight 2D line");
        split_at_depth_breaks(lines, strings, edgels, matches, &Lines3dParams::default(), &p2)
    }

    #[test]
    fn a_line_whose_disparity_breaks_is_split_there() {
        // Two edges in one straight image line: disparity rises to 210 over 50 edgels, then
        // runs from 225 down (an edge nearer the cameras).
        let (edgels, strings, matches) =
            string_with(|k| if k < 50 { 200.0 + 0.2 * k as f32 } else { 225.0 - 0.1 * (k - 50) as f32 });
        let lines = split(&edgels, &strings, &matches);
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines[0].last <= 49 && lines[0].last >= 45, "{lines:?}");
        assert!(lines[1].first >= 50 && lines[1].first <= 54, "{lines:?}");
        // Each side then carries a 3D line on all its matches.
        for l in &lines {
            let disparity: Vec<f64> = matches.iter().map(|m| m.disparity as f64).collect();
            let pts = disparities_along(l, &strings, &edgels, &disparity, &Lines3dParams::default()).unwrap();
            let pairs: Vec<(f64, f64)> = pts.iter().map(|&(s, d, _)| (s, d)).collect();
            assert_eq!(inliers_of_one_fit(&pairs, 1.0), pairs.len());
        }
    }

    /// Matches 0.7 px off a steady disparity are inside the fit's `max_residual` (1 px) and do
    /// not move the line much, but the front end does not vouch for them; those half a pixel
    /// or nearer it does, and those 3 px off neither carry nor join the line.
    #[test]
    fn only_matches_within_half_a_pixel_of_the_fit_are_vouched_for() {
        let off = |k: usize| match k % 10 {
            3 => 0.7,
            6 => -0.3,
            9 => 3.0,
            _ => 0.0,
        };
        let (edgels, strings, matches) = string_with(|k| 200.0 + 0.05 * k as f32 + off(k));
        let lines = fit_lines(&edgels, &strings, &Lines2dParams::default());
        let rect = crate::front_end::rectify::Rectification::new(&crate::front_end::rectify::tests::verged_pair());
        let lines3d = fit_lines3d(&lines, &strings, &edgels, &matches, &rect, &Lines3dParams::default());
        assert_eq!(lines3d.len(), 1);
        let l = &lines3d[0];
        assert_eq!(l.matches, 72, "the fit keeps all but the 3 px matches");
        let mut vouched = l.inliers.clone();
        vouched.sort_unstable();
        let expected: Vec<u32> = (0..80).filter(|k| k % 10 != 3 && k % 10 != 9).collect();
        assert_eq!(vouched, expected);
    }

    #[test]
    fn a_line_with_a_few_wrong_matches_is_not_split() {
        // One edge, its disparity rising steadily; four matches 6 px off.
        let (edgels, strings, matches) = string_with(|k| 200.0 + 0.2 * k as f32 + if k % 20 == 7 { 6.0 } else { 0.0 });
        assert_eq!(split(&edgels, &strings, &matches).len(), 1);
        // Nor is one whose second half is noise rather than a second edge.
        let (edgels, strings, matches) =
            string_with(|k| if k < 50 { 200.0 + 0.2 * k as f32 } else { 215.0 + 3.0 * ((k * 7) % 5) as f32 });
        assert_eq!(split(&edgels, &strings, &matches).len(), 1);
    }
}
