//! 2D geometry: each edge string cut into straight lines by recursive fit and segment.
//!
//! A stretch of string is split at the edgel farthest from the chord between its ends until
//! every piece lies within `tolerance` of its chord (the stretches most amenable to a line are
//! found first, corners last); each piece is then fitted by orthogonal regression, trimmed of
//! end edgels that leave the fit (corner blur), and kept if long enough.

use super::canny::Edgel;
use super::strings::EdgeString;
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Lines2dParams {
    /// Largest distance of an edgel from its line, pixels.
    pub tolerance: f32,
    /// Fewest edgels on a line.
    pub min_edgels: usize,
}

impl Default for Lines2dParams {
    fn default() -> Self {
        Lines2dParams { tolerance: 0.8, min_edgels: 6 }
    }
}

/// A straight line fitted to a run of one string's edgels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Line2 {
    /// Ends: the first and last edgels of the run, projected onto the fitted line.
    pub start: [f32; 2],
    pub end: [f32; 2],
    /// Which string, and which of its edgels (positions in the string, `first..=last`).
    pub string: u32,
    pub first: u32,
    pub last: u32,
    /// Root-mean-square distance of the edgels from the line, pixels.
    pub rms: f32,
}

impl Line2 {
    pub fn length(&self) -> f32 {
        ((self.end[0] - self.start[0]).powi(2) + (self.end[1] - self.start[1]).powi(2)).sqrt()
    }

    /// Unit direction from `start` to `end`.
    pub fn direction(&self) -> [f32; 2] {
        let l = self.length().max(1e-9);
        [(self.end[0] - self.start[0]) / l, (self.end[1] - self.start[1]) / l]
    }
}

/// Orthogonal regression: centroid and unit direction of the best-fitting line.
pub fn fit_line(pts: &[[f32; 2]]) -> ([f32; 2], [f32; 2]) {
    let n = pts.len() as f64;
    let (mx, my) = pts.iter().fold((0.0, 0.0), |(a, b), p| (a + p[0] as f64, b + p[1] as f64));
    let (mx, my) = (mx / n, my / n);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        let (dx, dy) = (p[0] as f64 - mx, p[1] as f64 - my);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    ([mx as f32, my as f32], [angle.cos() as f32, angle.sin() as f32])
}

fn distance_to_line(p: [f32; 2], centre: [f32; 2], dir: [f32; 2]) -> f32 {
    ((p[0] - centre[0]) * dir[1] - (p[1] - centre[1]) * dir[0]).abs()
}

/// Lines along every string. `edgels` are the positions the lines are fitted in (rectified or not).
pub fn fit_lines(edgels: &[Edgel], strings: &[EdgeString], p: &Lines2dParams) -> Vec<Line2> {
    let mut out = Vec::new();
    for (si, s) in strings.iter().enumerate() {
        let pts: Vec<[f32; 2]> = s.edgels.iter().map(|&i| [edgels[i as usize].x, edgels[i as usize].y]).collect();
        let mut pieces = Vec::new();
        split(&pts, 0, pts.len() - 1, p.tolerance, &mut pieces);
        for (a, b) in pieces {
            if let Some(line) = fit_piece(&pts, a, b, si as u32, p) {
                out.push(line);
            }
        }
    }
    out
}

/// Splits `pts[a..=b]` at the point farthest from its chord until every piece is within `tol`.
fn split(pts: &[[f32; 2]], a: usize, b: usize, tol: f32, out: &mut Vec<(usize, usize)>) {
    if b <= a + 1 {
        out.push((a, b));
        return;
    }
    let (pa, pb) = (pts[a], pts[b]);
    let len = ((pb[0] - pa[0]).powi(2) + (pb[1] - pa[1]).powi(2)).sqrt();
    let (far, dist) = (a + 1..b)
        .map(|k| {
            let d = if len < 1e-6 {
                ((pts[k][0] - pa[0]).powi(2) + (pts[k][1] - pa[1]).powi(2)).sqrt()
            } else {
                distance_to_line(pts[k], pa, [(pb[0] - pa[0]) / len, (pb[1] - pa[1]) / len])
            };
            (k, d)
        })
        .fold((a, -1.0f32), |best, c| if c.1 > best.1 { c } else { best });
    if dist <= tol {
        out.push((a, b));
    } else {
        split(pts, a, far, tol, out);
        split(pts, far, b, tol, out);
    }
}

/// Fits `pts[a..=b]`, trimming end edgels off the fit, and makes a line if enough remain.
pub(crate) fn fit_piece(pts: &[[f32; 2]], mut a: usize, mut b: usize, string: u32, p: &Lines2dParams) -> Option<Line2> {
    loop {
        if b + 1 < a + p.min_edgels {
            return None;
        }
        let (c, d) = fit_line(&pts[a..=b]);
        let (da, db) = (distance_to_line(pts[a], c, d), distance_to_line(pts[b], c, d));
        if da > p.tolerance / 2.0 && da >= db {
            a += 1;
            continue;
        }
        if db > p.tolerance / 2.0 {
            b -= 1;
            continue;
        }
        let project = |q: [f32; 2]| {
            let t = (q[0] - c[0]) * d[0] + (q[1] - c[1]) * d[1];
            [c[0] + t * d[0], c[1] + t * d[1]]
        };
        let rms =
            (pts[a..=b].iter().map(|&q| distance_to_line(q, c, d).powi(2)).sum::<f32>() / (b - a + 1) as f32).sqrt();
        return Some(Line2 {
            start: project(pts[a]),
            end: project(pts[b]),
            string,
            first: a as u32,
            last: b as u32,
            rms,
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn edgel(x: f32, y: f32) -> Edgel {
        Edgel { x, y, orientation: 0.0, contrast: 10.0, sides: [0.0; 2] }
    }

    #[test]
    fn an_l_shaped_string_gives_two_lines_meeting_at_the_corner() {
        // 30 edgels along x, then 20 up along y, with a little wobble.
        let mut e: Vec<Edgel> = (0..30).map(|k| edgel(10.0 + k as f32, 50.0 + 0.2 * ((k % 3) as f32 - 1.0))).collect();
        e.extend((1..=20).map(|k| edgel(39.0, 50.0 - k as f32)));
        let strings = vec![EdgeString { edgels: (0..e.len() as u32).collect() }];
        let lines = fit_lines(&e, &strings, &Lines2dParams::default());
        assert_eq!(lines.len(), 2, "{lines:?}");
        let (h, v) = (&lines[0], &lines[1]);
        assert!(h.direction()[1].abs() < 0.02 && (h.start[1] - 50.0).abs() < 0.1);
        assert!(v.direction()[0].abs() < 0.02 && (v.start[0] - 39.0).abs() < 0.1);
        assert!(h.length() > 26.0 && v.length() > 16.0);
        assert!(h.rms < 0.2);
    }

    #[test]
    fn short_strings_make_no_lines() {
        let e: Vec<Edgel> = (0..5).map(|k| edgel(k as f32, 0.0)).collect();
        let strings = vec![EdgeString { edgels: (0..5).collect() }];
        assert!(fit_lines(&e, &strings, &Lines2dParams::default()).is_empty());
    }

    #[test]
    fn orthogonal_regression_recovers_a_steep_line() {
        let pts: Vec<[f32; 2]> = (0..50).map(|k| [100.0 + 0.05 * k as f32, 10.0 + k as f32]).collect();
        let (_, d) = fit_line(&pts);
        let expected = 0.05f32.atan2(1.0);
        let got = d[0].atan2(d[1]).abs();
        assert!((got - expected).abs() < 1e-4, "{got} vs {expected}");
    }
}
