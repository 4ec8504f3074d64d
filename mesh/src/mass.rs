//! Mass properties of a closed, outward-oriented triangle mesh, by summing signed tetrahedra
//! from the origin (the divergence theorem).

use crate::trimesh::TriMesh;
use nalgebra::{Matrix3, Point3};

/// Mass, centre of mass and inertia tensor (about the centre of mass, in the model frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    pub volume: f64,
    pub mass: f64,
    pub centre_of_mass: Point3<f64>,
    pub inertia: Matrix3<f64>,
}

/// Signed volume: positive when the triangles face outwards.
pub fn signed_volume(mesh: &TriMesh) -> f64 {
    (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.corners(t);
            a.coords.dot(&b.coords.cross(&c.coords)) / 6.0
        })
        .sum()
}

/// Mass properties of the solid bounded by `mesh` at `density` (kg/m^3).
pub fn mass_properties(mesh: &TriMesh, density: f64) -> MassProperties {
    // Second moment of the canonical tetrahedron (0, e1, e2, e3), scaled by its determinant.
    let canonical = Matrix3::new(2.0, 1.0, 1.0, 1.0, 2.0, 1.0, 1.0, 1.0, 2.0) / 120.0;
    let (mut volume, mut first, mut second) = (0.0, nalgebra::Vector3::zeros(), Matrix3::zeros());
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.corners(t);
        let edges = Matrix3::from_columns(&[a.coords, b.coords, c.coords]);
        let det = edges.determinant();
        volume += det / 6.0;
        first += det / 24.0 * (a.coords + b.coords + c.coords);
        second += det * edges * canonical * edges.transpose();
    }
    let com = first / volume;
    let mass = density * volume;
    // Covariance about the centre of mass, then inertia = trace(C) I - C.
    let cov = density * second - mass * com * com.transpose();
    let inertia = Matrix3::identity() * cov.trace() - cov;
    MassProperties { volume, mass, centre_of_mass: com.into(), inertia }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Vector3};

    #[test]
    fn box_matches_closed_form() {
        let (x, y, z) = (0.06, 0.04, 0.03);
        let offset = Isometry3::translation(0.01, -0.02, 0.005);
        let mesh = TriMesh::cuboid(Vector3::new(x, y, z) / 2.0, 1.0).transformed(&offset);
        let mp = mass_properties(&mesh, 1000.0);
        let mass = 1000.0 * x * y * z;
        assert!((mp.mass - mass).abs() < 1e-12);
        assert!((mp.centre_of_mass - Point3::new(0.01, -0.02, 0.005)).norm() < 1e-12);
        let expect = Matrix3::from_diagonal(&Vector3::new(y * y + z * z, x * x + z * z, x * x + y * y)) * (mass / 12.0);
        assert!((mp.inertia - expect).norm() < 1e-12, "{} vs {}", mp.inertia, expect);
    }
}
