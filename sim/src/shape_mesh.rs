//! Colliders' convex primitives (boxes, cylinders, balls, capsules) as triangle meshes in the
//! world, for the renderer: how the arm, which has only collision shapes, is drawn.

use crate::convert;
use mesh::TriMesh;
use nalgebra::{Point3, Vector3};
use rapier3d::prelude::*;

/// Segments round a cylinder's or capsule's circumference.
const ROUND: u32 = 24;

/// The collider's shape at its pose, of one albedo, if it is a primitive this knows.
pub fn collider_mesh(collider: &Collider, albedo: f32) -> Option<TriMesh> {
    let shape = collider.shape();
    let (vertices, triangles) = if let Some(c) = shape.as_cuboid() {
        c.to_trimesh()
    } else if let Some(c) = shape.as_cylinder() {
        c.to_trimesh(ROUND)
    } else if let Some(b) = shape.as_ball() {
        b.to_trimesh(ROUND, ROUND / 2)
    } else if let Some(c) = shape.as_capsule() {
        c.to_trimesh(ROUND, ROUND / 2)
    } else {
        return None;
    };
    let world_from_shape = convert::iso(collider.position());
    let vertices: Vec<Point3<f64>> =
        vertices.iter().map(|v| world_from_shape * Point3::new(v.x as f64, v.y as f64, v.z as f64)).collect();
    Some(outward(TriMesh { albedo: vec![albedo; triangles.len()], vertices, triangles }))
}

/// The mesh with every triangle wound to face away from its centroid (the shapes are convex).
fn outward(mut m: TriMesh) -> TriMesh {
    let n = m.vertices.len().max(1) as f64;
    let centre = Point3::from(m.vertices.iter().map(|p| p.coords).sum::<Vector3<f64>>() / n);
    for t in 0..m.triangles.len() {
        let [a, b, c] = m.corners(t);
        if (b - a).cross(&(c - a)).dot(&(a - centre)) < 0.0 {
            m.triangles[t].swap(1, 2);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_become_closed_outward_meshes_at_their_pose() {
        let at = Pose::from_translation(Vector::new(0.1, 0.2, 0.3));
        for builder in [
            ColliderBuilder::cuboid(0.01, 0.02, 0.03),
            ColliderBuilder::cylinder(0.02, 0.01),
            ColliderBuilder::ball(0.01),
        ] {
            let m = collider_mesh(&builder.position(at).build(), 0.5).unwrap();
            let centre = Point3::new(0.1, 0.2, 0.3);
            for t in 0..m.triangles.len() {
                let [a, b, c] = m.corners(t);
                let normal = (b - a).cross(&(c - a));
                assert!(normal.dot(&(a - centre)) >= 0.0, "triangle {t} faces inwards");
            }
            // Closed: the enclosed volume by the divergence theorem is positive.
            let volume: f64 = (0..m.triangles.len())
                .map(|t| {
                    let [a, b, c] = m.corners(t);
                    (a - centre).dot(&(b - centre).cross(&(c - centre))) / 6.0
                })
                .sum();
            assert!(volume > 0.0);
        }
    }
}
