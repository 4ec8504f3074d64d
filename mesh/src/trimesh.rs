//! Indexed triangle meshes: counter-clockwise triangles seen from outside, one albedo per face.

use nalgebra::{Isometry3, Point3, Vector3};

/// A triangle mesh in metres. Triangles wind counter-clockwise seen from outside, so
/// `(b - a) x (c - a)` points out of the solid.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<Point3<f64>>,
    pub triangles: Vec<[u32; 3]>,
    /// Diffuse reflectance (0-1) of each triangle.
    pub albedo: Vec<f32>,
}

/// Where the line `o + t d` crosses triangle `[a, b, c]`: the parameter `t` (of either sign),
/// or `None` if it misses or runs parallel to it (Moller-Trumbore).
pub fn ray_triangle(o: &Point3<f64>, d: &Vector3<f64>, [a, b, c]: &[Point3<f64>; 3]) -> Option<f64> {
    let (e1, e2) = (b - a, c - a);
    let p = d.cross(&e2);
    let det = e1.dot(&p);
    if det.abs() < 1e-15 {
        return None;
    }
    let s = o - a;
    let u = s.dot(&p) / det;
    let q = s.cross(&e1);
    let v = d.dot(&q) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then(|| e2.dot(&q) / det)
}

/// Whether point `p` lies inside the closed surface made of `triangles`: a ray from it crosses
/// the surface an odd number of times. The ray runs in a direction no model edge or face is
/// likely to share, so that it does not graze one.
pub fn encloses(triangles: &[[Point3<f64>; 3]], p: &Point3<f64>) -> bool {
    let d = Vector3::new(0.8017, 0.4629, 0.3781);
    triangles.iter().filter_map(|t| ray_triangle(p, &d, t)).filter(|&t| t > 0.0).count() % 2 == 1
}

impl TriMesh {
    /// The three corners of triangle `t`.
    pub fn corners(&self, t: usize) -> [Point3<f64>; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// Unit outward normal of triangle `t` (zero for a degenerate triangle).
    pub fn face_normal(&self, t: usize) -> Vector3<f64> {
        let [a, b, c] = self.corners(t);
        (b - a).cross(&(c - a)).try_normalize(1e-15).unwrap_or_else(Vector3::zeros)
    }

    /// Appends `other`, keeping its albedo.
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.triangles.extend(other.triangles.iter().map(|t| t.map(|i| i + base)));
        self.albedo.extend_from_slice(&other.albedo);
    }

    /// The mesh moved by `iso`.
    pub fn transformed(&self, iso: &Isometry3<f64>) -> TriMesh {
        TriMesh {
            vertices: self.vertices.iter().map(|p| iso * p).collect(),
            triangles: self.triangles.clone(),
            albedo: self.albedo.clone(),
        }
    }

    /// Reverses every triangle's winding (turns normals inside out).
    pub fn flip(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Axis-aligned bounds `(min, max)`; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        let first = *self.vertices.first()?;
        Some(self.vertices.iter().fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))))
    }

    /// Radius of the smallest origin-centred sphere holding every vertex.
    pub fn radius(&self) -> f64 {
        self.vertices.iter().map(|p| p.coords.norm()).fold(0.0, f64::max)
    }

    /// True when every edge is shared by exactly two triangles, in opposite directions.
    pub fn is_closed(&self) -> bool {
        let mut directed = std::collections::HashMap::new();
        for t in &self.triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_insert(0u32) += 1;
            }
        }
        directed.iter().all(|(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1))
    }

    /// A box with half extents `half`, centred at the origin, of one albedo.
    pub fn cuboid(half: Vector3<f64>, albedo: f32) -> TriMesh {
        let corner = |i: u32| {
            Point3::new(
                if i & 1 == 0 { -half.x } else { half.x },
                if i & 2 == 0 { -half.y } else { half.y },
                if i & 4 == 0 { -half.z } else { half.z },
            )
        };
        // Faces as quads of corner indices, counter-clockwise seen from outside.
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles: Vec<[u32; 3]> = quads.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
        TriMesh { vertices: (0..8).map(corner).collect(), albedo: vec![albedo; triangles.len()], triangles }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cuboid_is_closed_with_outward_normals() {
        let m = TriMesh::cuboid(Vector3::new(0.1, 0.2, 0.3), 0.5);
        assert!(m.is_closed());
        for t in 0..m.triangles.len() {
            let [a, b, c] = m.corners(t);
            let centroid = (a.coords + b.coords + c.coords) / 3.0;
            assert!(m.face_normal(t).dot(&centroid) > 0.0, "triangle {t} faces inwards");
        }
    }

    /// Points of a box are inside it exactly when within its half extents, on a grid a hair off
    /// the planes of its faces (so its rays pass close by the box's edges).
    #[test]
    fn a_box_encloses_exactly_the_points_within_it() {
        let half = Vector3::new(0.02, 0.015, 0.01);
        let m = TriMesh::cuboid(half, 0.5);
        let triangles: Vec<[Point3<f64>; 3]> = (0..m.triangles.len()).map(|t| m.corners(t)).collect();
        let mut inside = 0;
        for i in -6..=6 {
            for j in -6..=6 {
                for k in -6..=6 {
                    let p = Point3::new(i as f64 * 0.005 + 1e-6, j as f64 * 0.004 + 1e-6, k as f64 * 0.003 + 1e-6);
                    let within = p.x.abs() < half.x && p.y.abs() < half.y && p.z.abs() < half.z;
                    assert_eq!(encloses(&triangles, &p), within, "{p:?}");
                    inside += usize::from(within);
                }
            }
        }
        assert!(inside > 50, "only {inside} points inside");
    }
}
