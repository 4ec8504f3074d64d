//! 3D geometry: along each 2D line (fitted in rectified left coordinates), the matched edgels
//! give (arc length, disparity) pairs; a robust straight-line fit of disparity against arc
//! length, projected through the calibration at the line's ends, gives a 3D segment in the
//! `cam` frame with the depth uncertainty of each end.

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
    /// (0 for a line completed from its neighbours, see [`complete_flat_lines`]).
    pub line2: u32,
    pub matches: u32,
    /// The left edgels whose matches agree with the fit (the inliers).
    #[serde(skip)]
    pub inliers: Vec<u32>,
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
        if (dir[1].abs() as f64) < (p.min_angle_to_raster as f64).sin() || len < 1.0 {
            continue;
        }
        let string = &strings[line.string as usize].edgels;
        let along = |i: u32| {
            let e = &left_rect[i as usize];
            ((e.x - line.start[0]) * dir[0] + (e.y - line.start[1]) * dir[1]) as f64
        };
        let mut points: Vec<(f64, f64, u32)> = string[line.first as usize..=line.last as usize]
            .iter()
            .filter(|&&i| !disparity[i as usize].is_nan())
            .map(|&i| (along(i), disparity[i as usize], i))
            .collect();
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
            inliers: points.iter().map(|&(.., i)| i).collect(),
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
            inliers: Vec::new(),
        });
    }
    lines3d.extend(added);
}
