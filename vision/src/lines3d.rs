//! 3D geometry: along each 2D line (fitted in rectified left coordinates), the matched edgels
//! give (arc length, disparity) pairs; a robust straight-line fit of disparity against arc
//! length, projected through the calibration at the line's ends, gives a 3D segment in the
//! `cam` frame with the depth uncertainty of each end.

use crate::lines2d::Line2;
use crate::pmf::Match;
use crate::rectify::Rectification;
use crate::strings::EdgeString;
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
        Lines3dParams {
            min_matches: 6,
            min_span: 0.5,
            min_angle_to_raster: 0.35,
            max_residual: 1.0,
            max_slope: 1.5,
        }
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
    /// The 2D line it came from (index into the 2D lines) and how many matches carried it.
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
    let (ms, md) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), &(s, d)| (a + s, b + d));
    let (ms, md) = (ms / n, md / n);
    let sss: f64 = points.iter().map(|&(s, _)| (s - ms).powi(2)).sum();
    if sss < 1e-9 || points.len() < 3 {
        return None;
    }
    let beta = points
        .iter()
        .map(|&(s, d)| (s - ms) * (d - md))
        .sum::<f64>()
        / sss;
    let alpha = md - beta * ms;
    let var = points
        .iter()
        .map(|&(s, d)| (d - alpha - beta * s).powi(2))
        .sum::<f64>()
        / (n - 2.0).max(1.0);
    Some((alpha, beta, var, ms, sss))
}

/// 3D lines from 2D lines (fitted on the rectified left edgels `left_rect`) and PMF matches.
pub fn fit_lines3d(
    lines: &[Line2],
    strings: &[EdgeString],
    left_rect: &[crate::canny::Edgel],
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
        let pairs =
            |pts: &[(f64, f64, u32)]| pts.iter().map(|&(s, d, _)| (s, d)).collect::<Vec<_>>();
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
        let (lo, hi) = points
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &(s, ..)| {
                (a.min(s), b.max(s))
            });
        if (hi - lo) < p.min_span as f64 * len || beta.abs() > p.max_slope as f64 {
            continue;
        }
        let n = points.len() as f64;
        let end = |s: f64| {
            let d = alpha + beta * s;
            let sigma_d = (var * (1.0 / n + (s - ms).powi(2) / sss)).sqrt();
            let (x, y) = (
                line.start[0] as f64 + s * dir[0] as f64,
                line.start[1] as f64 + s * dir[1] as f64,
            );
            let point = rect.triangulate(x, y, d);
            let depth = rect.f * rect.baseline / d;
            (point, depth * depth * sigma_d / (rect.f * rect.baseline))
        };
        let ((a, sigma_a), (b, sigma_b)) = (end(0.0), end(len));
        if !(a
            .coords
            .iter()
            .chain(b.coords.iter())
            .all(|c| c.is_finite()))
        {
            continue;
        }
        out.push(Line3 {
            a: [a.x, a.y, a.z],
            b: [b.x, b.y, b.z],
            sigma_a,
            sigma_b,
            line2: li as u32,
            matches: points.len() as u32,
            inliers: points.iter().map(|&(.., i)| i).collect(),
        });
    }
    out
}
