//! Simple 2D polygons: orientation, ear-clipping triangulation, and an exact convex
//! decomposition (Hertel-Mehlhorn: triangulate, then drop every diagonal whose removal keeps
//! the merged piece convex). Written by hand because the profiles are tiny and the crates for
//! this either triangulate only or approximate.

use nalgebra::Point2;

/// Twice the signed area: positive for counter-clockwise polygons.
pub fn signed_area2(pts: &[Point2<f64>]) -> f64 {
    (0..pts.len())
        .map(|i| {
            let (a, b) = (pts[i], pts[(i + 1) % pts.len()]);
            a.x * b.y - b.x * a.y
        })
        .sum()
}

fn cross(o: Point2<f64>, a: Point2<f64>, b: Point2<f64>) -> f64 {
    (a - o).perp(&(b - o))
}

fn segments_cross(a: Point2<f64>, b: Point2<f64>, c: Point2<f64>, d: Point2<f64>) -> bool {
    let (d1, d2) = (cross(a, b, c), cross(a, b, d));
    let (d3, d4) = (cross(c, d, a), cross(c, d, b));
    d1 * d2 < 0.0 && d3 * d4 < 0.0
}

/// Checks a profile: at least 3 distinct vertices, no edge crossing another, non-zero area.
pub fn validate_simple(pts: &[Point2<f64>]) -> Result<(), String> {
    let n = pts.len();
    if n < 3 {
        return Err(format!("a profile needs at least 3 vertices, got {n}"));
    }
    for i in 0..n {
        if (pts[i] - pts[(i + 1) % n]).norm() < 1e-12 {
            return Err(format!("vertices {i} and {} coincide", (i + 1) % n));
        }
        for j in i + 2..n {
            if (j + 1) % n == i {
                continue;
            }
            if segments_cross(pts[i], pts[(i + 1) % n], pts[j], pts[(j + 1) % n]) {
                return Err(format!("edge {i} crosses edge {j}: the profile is not simple"));
            }
        }
    }
    if signed_area2(pts).abs() < 1e-12 {
        return Err("the profile has zero area".into());
    }
    Ok(())
}

/// Triangulates a simple counter-clockwise polygon by ear clipping. Returns index triples,
/// counter-clockwise.
pub fn triangulate(pts: &[Point2<f64>]) -> Vec<[usize; 3]> {
    let mut ring: Vec<usize> = (0..pts.len()).collect();
    let mut out = Vec::with_capacity(pts.len().saturating_sub(2));
    while ring.len() > 3 {
        let n = ring.len();
        let ear = (0..n).find(|&i| {
            let (a, b, c) = (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
            cross(pts[a], pts[b], pts[c]) > 1e-15
                && ring
                    .iter()
                    .all(|&k| k == a || k == b || k == c || !point_in_triangle(pts[k], pts[a], pts[b], pts[c]))
        });
        // A simple polygon always has an ear; if rounding hides it, clip the flattest corner.
        let i = ear.unwrap_or(0);
        out.push([ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]]);
        ring.remove(i);
    }
    out.push([ring[0], ring[1], ring[2]]);
    out
}

fn point_in_triangle(p: Point2<f64>, a: Point2<f64>, b: Point2<f64>, c: Point2<f64>) -> bool {
    cross(a, b, p) >= 0.0 && cross(b, c, p) >= 0.0 && cross(c, a, p) >= 0.0
}

fn is_convex(pts: &[Point2<f64>], ring: &[usize]) -> bool {
    let n = ring.len();
    (0..n).all(|i| cross(pts[ring[i]], pts[ring[(i + 1) % n]], pts[ring[(i + 2) % n]]) >= -1e-12)
}

/// Merges two counter-clockwise pieces that share the edge `a -> b` (in `p`) / `b -> a` (in `q`).
fn merge_across(p: &[usize], q: &[usize], a: usize, b: usize) -> Vec<usize> {
    let rot = |ring: &[usize], start: usize| {
        let s = ring.iter().position(|&v| v == start).expect("shared vertex");
        ring[s..].iter().chain(&ring[..s]).copied().collect::<Vec<_>>()
    };
    let mut merged = rot(p, b); // b ... a
    let from_a = rot(q, a); // a ... b
    merged.extend_from_slice(&from_a[1..from_a.len() - 1]);
    merged
}

fn shared_edge(p: &[usize], q: &[usize]) -> Option<(usize, usize)> {
    (0..p.len())
        .map(|i| (p[i], p[(i + 1) % p.len()]))
        .find(|&(a, b)| (0..q.len()).any(|j| q[j] == b && q[(j + 1) % q.len()] == a))
}

/// Splits a simple counter-clockwise polygon into convex counter-clockwise pieces whose union
/// is exactly the polygon (at most four times the minimum number of pieces).
pub fn convex_decomposition(pts: &[Point2<f64>]) -> Vec<Vec<usize>> {
    let mut pieces: Vec<Vec<usize>> = triangulate(pts).into_iter().map(|t| t.to_vec()).collect();
    'merge: loop {
        for i in 0..pieces.len() {
            for j in i + 1..pieces.len() {
                let Some((a, b)) = shared_edge(&pieces[i], &pieces[j]) else {
                    continue;
                };
                let merged = merge_across(&pieces[i], &pieces[j], a, b);
                if is_convex(pts, &merged) {
                    pieces[i] = merged;
                    pieces.swap_remove(j);
                    continue 'merge;
                }
            }
        }
        return pieces;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn l_shape() -> Vec<Point2<f64>> {
        [(0.0, 0.0), (3.0, 0.0), (3.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)]
            .map(|(x, y)| Point2::new(x, y))
            .to_vec()
    }

    fn area_of(pts: &[Point2<f64>], ring: &[usize]) -> f64 {
        signed_area2(&ring.iter().map(|&i| pts[i]).collect::<Vec<_>>()) / 2.0
    }

    #[test]
    fn triangulation_covers_the_area_with_ccw_triangles() {
        let pts = l_shape();
        let tris = triangulate(&pts);
        assert_eq!(tris.len(), pts.len() - 2);
        let total: f64 = tris.iter().map(|t| area_of(&pts, t)).sum();
        assert!((total - 4.0).abs() < 1e-12);
        assert!(tris.iter().all(|t| area_of(&pts, t) > 0.0));
    }

    #[test]
    fn convex_decomposition_of_an_l_is_two_convex_pieces() {
        let pts = l_shape();
        let pieces = convex_decomposition(&pts);
        assert_eq!(pieces.len(), 2);
        assert!(pieces.iter().all(|p| is_convex(&pts, p)));
        let total: f64 = pieces.iter().map(|p| area_of(&pts, p)).sum();
        assert!((total - 4.0).abs() < 1e-12);
    }

    #[test]
    fn convex_polygon_stays_whole() {
        let hex: Vec<_> = (0..6)
            .map(|k| {
                let a = k as f64 * std::f64::consts::FRAC_PI_3;
                Point2::new(a.cos(), a.sin())
            })
            .collect();
        assert_eq!(convex_decomposition(&hex).len(), 1);
    }

    #[test]
    fn self_crossing_profile_is_rejected() {
        let bow = [(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)].map(|(x, y)| Point2::new(x, y));
        assert!(validate_simple(&bow).unwrap_err().contains("crosses"));
        assert!(validate_simple(&l_shape()).is_ok());
    }
}
