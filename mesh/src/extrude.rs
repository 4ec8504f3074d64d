//! Extruded-profile models: a simple polygon in the model's `xy` plane, extruded along `z`
//! from `-thickness/2` to `+thickness/2`. A rectangular profile may carry a checker pattern on
//! both caps (the calibration flag).

use crate::polygon;
use crate::trimesh::TriMesh;
use nalgebra::{Point2, Point3};

/// Albedo of the dark squares of a checker pattern.
pub const CHECKER_DARK: f32 = 0.06;

/// A profile ready to extrude: counter-clockwise, in metres.
#[derive(Debug, Clone)]
pub struct Extrusion {
    pub profile: Vec<Point2<f64>>,
    pub thickness: f64,
}

impl Extrusion {
    /// Checks the profile and orients it counter-clockwise.
    pub fn new(mut profile: Vec<Point2<f64>>, thickness: f64) -> Result<Self, String> {
        polygon::validate_simple(&profile)?;
        if thickness.is_nan() || thickness <= 0.0 {
            return Err(format!("thickness must be positive, got {thickness}"));
        }
        if polygon::signed_area2(&profile) < 0.0 {
            profile.reverse();
        }
        Ok(Extrusion { profile, thickness })
    }

    fn lift(&self, p: Point2<f64>, top: bool) -> Point3<f64> {
        let h = self.thickness / 2.0;
        Point3::new(p.x, p.y, if top { h } else { -h })
    }

    /// The closed surface: caps triangulated by ear clipping, one quad per side.
    pub fn mesh(&self, albedo: f32) -> TriMesh {
        let n = self.profile.len() as u32;
        let mut vertices: Vec<Point3<f64>> = self.profile.iter().map(|&p| self.lift(p, false)).collect();
        vertices.extend(self.profile.iter().map(|&p| self.lift(p, true)));
        let mut triangles = Vec::new();
        for [a, b, c] in polygon::triangulate(&self.profile) {
            let [a, b, c] = [a, b, c].map(|i| i as u32);
            triangles.push([a + n, b + n, c + n]); // top, seen from +z: counter-clockwise
            triangles.push([a, c, b]); // bottom, seen from -z
        }
        triangles.extend(side_quads(n, |i| i, |i| i + n));
        TriMesh { albedo: vec![albedo; triangles.len()], vertices, triangles }
    }

    /// Exact convex decomposition: each convex piece of the profile, extruded, as its corners.
    pub fn convex_pieces(&self) -> Vec<Vec<Point3<f64>>> {
        polygon::convex_decomposition(&self.profile)
            .into_iter()
            .map(|ring| {
                let flat = ring.iter().map(|&i| self.profile[i]);
                flat.clone().map(|p| self.lift(p, false)).chain(flat.map(|p| self.lift(p, true))).collect()
            })
            .collect()
    }

    /// A rectangular plate whose caps carry an `nx` x `ny` checker of `albedo` and
    /// [`CHECKER_DARK`], inside a plain border `margin` wide (metres; 0 for none). The square
    /// at the pattern's `-x -y` corner is light. The sides are split where the squares meet
    /// them, so the mesh stays closed without T-junctions.
    pub fn checker_mesh(&self, [nx, ny]: [u32; 2], albedo: f32, margin: f64) -> Result<TriMesh, String> {
        let (lo, hi) = self.rectangle()?;
        if !(margin >= 0.0 && 2.0 * margin < (hi.x - lo.x).min(hi.y - lo.y)) {
            return Err(format!("the checker's margin must leave room for the squares, got {margin} m"));
        }
        let lines = |lo: f64, hi: f64, n: u32| -> Vec<f64> {
            let inner = (0..=n).map(|i| lo + margin + (hi - lo - 2.0 * margin) * i as f64 / n as f64);
            if margin > 0.0 {
                std::iter::once(lo).chain(inner).chain(std::iter::once(hi)).collect()
            } else {
                inner.collect()
            }
        };
        let (xs, ys) = (lines(lo.x, hi.x, nx), lines(lo.y, hi.y, ny));
        let border = u32::from(margin > 0.0);
        let (gx, gy) = (xs.len() as u32 - 1, ys.len() as u32 - 1);
        let cols = gx + 1;
        let per_cap = cols * (gy + 1);
        let index = |i: u32, j: u32, top: bool| j * cols + i + if top { per_cap } else { 0 };
        let mut vertices = Vec::with_capacity(2 * per_cap as usize);
        for top in [false, true] {
            for y in &ys {
                for x in &xs {
                    vertices.push(self.lift(Point2::new(*x, *y), top));
                }
            }
        }
        let shade_of = |i: u32, j: u32| {
            let inside = (border..gx - border).contains(&i) && (border..gy - border).contains(&j);
            if !inside || (i + j - 2 * border).is_multiple_of(2) { albedo } else { CHECKER_DARK }
        };
        let (mut triangles, mut shade) = (Vec::new(), Vec::new());
        for j in 0..gy {
            for i in 0..gx {
                let [p, q, r, s] = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
                let t = |(x, y): (u32, u32)| index(x, y, true);
                let b = |(x, y): (u32, u32)| index(x, y, false);
                triangles.extend([[t(p), t(q), t(r)], [t(p), t(r), t(s)], [b(p), b(r), b(q)], [b(p), b(s), b(r)]]);
                shade.extend([shade_of(i, j); 4]);
            }
        }
        // The boundary ring of the grid, counter-clockwise.
        let ring: Vec<(u32, u32)> = (0..gx)
            .map(|i| (i, 0))
            .chain((0..gy).map(|j| (gx, j)))
            .chain((1..=gx).rev().map(|i| (i, gy)))
            .chain((1..=gy).rev().map(|j| (0, j)))
            .collect();
        let sides = side_quads(
            ring.len() as u32,
            |k| index(ring[k as usize].0, ring[k as usize].1, false),
            |k| index(ring[k as usize].0, ring[k as usize].1, true),
        );
        shade.extend(std::iter::repeat_n(albedo, sides.len()));
        triangles.extend(sides);
        Ok(TriMesh { vertices, triangles, albedo: shade })
    }

    fn rectangle(&self) -> Result<(Point2<f64>, Point2<f64>), String> {
        let lo = self.profile.iter().fold(self.profile[0], |m, p| m.inf(p));
        let hi = self.profile.iter().fold(self.profile[0], |m, p| m.sup(p));
        let on_corner = |p: &Point2<f64>| {
            ((p.x - lo.x).abs() < 1e-12 || (p.x - hi.x).abs() < 1e-12)
                && ((p.y - lo.y).abs() < 1e-12 || (p.y - hi.y).abs() < 1e-12)
        };
        if self.profile.len() == 4 && self.profile.iter().all(on_corner) {
            Ok((lo, hi))
        } else {
            Err("a checker pattern needs an axis-aligned rectangular profile".into())
        }
    }
}

/// Side walls between consecutive ring vertices, bottom index `bottom(k)`, top `top(k)`.
fn side_quads(n: u32, bottom: impl Fn(u32) -> u32, top: impl Fn(u32) -> u32) -> Vec<[u32; 3]> {
    (0..n)
        .flat_map(|k| {
            let next = (k + 1) % n;
            let (b0, b1, t0, t1) = (bottom(k), bottom(next), top(k), top(next));
            [[b0, b1, t1], [b0, t1, t0]]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square(side: f64) -> Vec<Point2<f64>> {
        let h = side / 2.0;
        vec![Point2::new(-h, -h), Point2::new(h, -h), Point2::new(h, h), Point2::new(-h, h)]
    }

    #[test]
    fn clockwise_profiles_are_reoriented_and_meshes_closed() {
        let mut cw = square(0.04);
        cw.reverse();
        let e = Extrusion::new(cw, 0.01).unwrap();
        assert!(polygon::signed_area2(&e.profile) > 0.0);
        assert!(e.mesh(0.5).is_closed());
    }

    #[test]
    fn checker_plate_is_closed_and_patterned() {
        let e = Extrusion::new(square(0.06), 0.004).unwrap();
        let m = e.checker_mesh([4, 3], 0.9, 0.0).unwrap();
        assert!(m.is_closed());
        let dark = m.albedo.iter().filter(|&&a| a == CHECKER_DARK).count();
        assert_eq!(dark, 2 * 2 * 6, "6 dark squares per cap, 2 triangles each, 2 caps");
    }

    #[test]
    fn a_checker_s_margin_is_plain_and_its_squares_even() {
        let e = Extrusion::new(square(0.1), 0.004).unwrap();
        let m = e.checker_mesh([4, 4], 0.9, 0.01).unwrap();
        assert!(m.is_closed());
        let dark: Vec<usize> = (0..m.triangles.len()).filter(|&t| m.albedo[t] == CHECKER_DARK).collect();
        assert_eq!(dark.len(), 2 * 2 * 8, "8 dark squares per cap, 2 triangles each, 2 caps");
        for t in dark {
            for &v in &m.triangles[t] {
                let p = m.vertices[v as usize];
                assert!(p.x.abs() <= 0.04 + 1e-12 && p.y.abs() <= 0.04 + 1e-12, "a dark square in the margin: {p}");
            }
        }
        assert!(e.checker_mesh([4, 4], 0.9, 0.05).is_err(), "no room for the squares");
    }

    #[test]
    fn checker_needs_a_rectangle() {
        let tri = vec![Point2::new(0.0, 0.0), Point2::new(1.0, 0.0), Point2::new(0.0, 1.0)];
        assert!(Extrusion::new(tri, 0.1).unwrap().checker_mesh([2, 2], 0.9, 0.0).is_err());
    }
}
