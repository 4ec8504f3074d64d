//! Wavefront OBJ models, read with `tobj`, welded, and oriented outwards.

use crate::trimesh::TriMesh;
use nalgebra::Point3;
use std::path::Path;

/// Loads every object of an OBJ file as one closed mesh, scaling coordinates by `to_m`.
pub fn load(path: &Path, to_m: f64, albedo: f32) -> Result<TriMesh, String> {
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, _materials) = tobj::load_obj(path, &options).map_err(|e| e.to_string())?;
    let mut mesh = TriMesh::default();
    for model in &models {
        let m = &model.mesh;
        let part = TriMesh {
            vertices: m
                .positions
                .chunks_exact(3)
                .map(|c| Point3::new(c[0] as f64, c[1] as f64, c[2] as f64) * to_m)
                .collect(),
            triangles: m.indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            albedo: vec![albedo; m.indices.len() / 3],
        };
        mesh.append(&part);
    }
    let mut mesh = weld(&mesh, 1e-9);
    if mesh.triangles.is_empty() {
        return Err("the file holds no faces".into());
    }
    if !mesh.is_closed() {
        return Err("the mesh is not closed (every edge must join exactly two faces)".into());
    }
    if crate::mass::signed_volume(&mesh) < 0.0 {
        mesh.flip();
    }
    Ok(mesh)
}

/// Merges vertices closer than `tol`, so faces that share a corner share its index.
pub fn weld(mesh: &TriMesh, tol: f64) -> TriMesh {
    let mut kept: Vec<Point3<f64>> = Vec::new();
    let remap: Vec<u32> = mesh
        .vertices
        .iter()
        .map(|p| {
            let found = kept.iter().position(|q| (q - p).norm() <= tol);
            found.unwrap_or_else(|| {
                kept.push(*p);
                kept.len() - 1
            }) as u32
        })
        .collect();
    TriMesh {
        vertices: kept,
        triangles: mesh.triangles.iter().map(|t| t.map(|i| remap[i as usize])).collect(),
        albedo: mesh.albedo.clone(),
    }
}

/// True when every vertex lies on or behind every face's plane (within `tol` metres).
pub fn is_convex(mesh: &TriMesh, tol: f64) -> bool {
    (0..mesh.triangles.len()).all(|t| {
        let n = mesh.face_normal(t);
        let a = mesh.corners(t)[0];
        mesh.vertices.iter().all(|p| n.dot(&(p - a)) <= tol)
    })
}
