//! The 3D wireframe the model matcher uses: straight feature edges, where two faces meet at a
//! dihedral angle of at least a threshold (20 deg by default) or a face has no neighbour.
//! Collinear pieces that meet end to end are merged into one segment.

use crate::trimesh::TriMesh;
use nalgebra::{Point3, Vector3};
use std::collections::HashMap;

/// Default minimum angle between the normals of adjacent faces for their edge to be a feature.
pub const FEATURE_ANGLE_DEG: f64 = 20.0;

/// A straight 3D line segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment3 {
    pub a: Point3<f64>,
    pub b: Point3<f64>,
}

impl Segment3 {
    pub fn length(&self) -> f64 {
        (self.b - self.a).norm()
    }

    pub fn direction(&self) -> Vector3<f64> {
        (self.b - self.a).normalize()
    }

    /// The point at fraction `t` from `a` to `b`.
    pub fn at(&self, t: f64) -> Point3<f64> {
        self.a + (self.b - self.a) * t
    }
}

/// The triangles along each edge (vertex indices, smaller first).
fn faces_of_edges(mesh: &TriMesh) -> HashMap<(u32, u32), Vec<usize>> {
    let mut faces_of_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            faces_of_edge.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    faces_of_edge
}

/// Feature edges of `mesh` (which should be welded: shared corners share an index).
pub fn feature_edges(mesh: &TriMesh, min_angle_deg: f64) -> Vec<Segment3> {
    let faces_of_edge = faces_of_edges(mesh);
    let cos_min = min_angle_deg.to_radians().cos();
    let mut edges: Vec<(u32, u32)> = faces_of_edge
        .iter()
        .filter(|(_, faces)| match faces.as_slice() {
            [f, g] => mesh.face_normal(*f).dot(&mesh.face_normal(*g)) <= cos_min,
            _ => true, // a border or a non-manifold edge is always a feature
        })
        .map(|(&e, _)| e)
        .collect();
    edges.sort_unstable(); // HashMap order is random; the wireframe must not be
    merge_collinear(mesh, &edges)
}

/// Markings: where the albedo changes across a flat face (a face's pattern, such as the
/// calibration flag's checker), merged into straight segments through the pattern's crossings.
/// They are lines a camera sees as well as the feature edges, though no solid edge lies there.
pub fn marking_edges(mesh: &TriMesh, min_angle_deg: f64) -> Vec<Segment3> {
    let faces_of_edge = faces_of_edges(mesh);
    let cos_min = min_angle_deg.to_radians().cos();
    let mut edges: Vec<(u32, u32)> = faces_of_edge
        .iter()
        .filter(|(_, faces)| match faces.as_slice() {
            [f, g] => {
                mesh.face_normal(*f).dot(&mesh.face_normal(*g)) > cos_min
                    && (mesh.albedo[*f] - mesh.albedo[*g]).abs() > MARKING_CONTRAST
            }
            _ => false,
        })
        .map(|(&e, _)| e)
        .collect();
    edges.sort_unstable();
    merge_straight(mesh, &edges)
}

/// Albedo difference across an edge for it to be a marking.
const MARKING_CONTRAST: f32 = 0.1;

/// Which vertices a merged segment may run through.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Through {
    /// Only those no other edge touches (feature edges: a corner where a third edge meets ends
    /// a segment).
    FreeVertices,
    /// Any vertex (a pattern's lines cross each other and run on).
    Crossings,
}

/// Joins feature edges that continue each other in a straight line through a vertex that
/// no other feature edge touches.
fn merge_collinear(mesh: &TriMesh, edges: &[(u32, u32)]) -> Vec<Segment3> {
    merge(mesh, edges, Through::FreeVertices)
}

/// Joins edges that continue each other in a straight line, through any vertex.
fn merge_straight(mesh: &TriMesh, edges: &[(u32, u32)]) -> Vec<Segment3> {
    merge(mesh, edges, Through::Crossings)
}

/// Edges joined into straight segments: from each edge not yet used, walk both ways onto the
/// edge that continues it straight on, through the vertices `through` allows.
fn merge(mesh: &TriMesh, edges: &[(u32, u32)], through: Through) -> Vec<Segment3> {
    let mut at_vertex: HashMap<u32, Vec<usize>> = HashMap::new();
    for (i, &(a, b)) in edges.iter().enumerate() {
        at_vertex.entry(a).or_default().push(i);
        at_vertex.entry(b).or_default().push(i);
    }
    let p = |v: u32| mesh.vertices[v as usize];
    let other_end = |e: usize, v: u32| if edges[e].0 == v { edges[e].1 } else { edges[e].0 };
    let mut used = vec![false; edges.len()];
    let mut out = Vec::new();
    for start in 0..edges.len() {
        if used[start] {
            continue;
        }
        used[start] = true;
        let (a, b) = edges[start];
        let dir = (p(b) - p(a)).normalize();
        let mut ends = [a, b];
        for (end, sign) in [(1usize, 1.0), (0usize, -1.0)] {
            loop {
                let here = ends[end];
                let touching = &at_vertex[&here];
                if through == Through::FreeVertices && touching.len() != 2 {
                    break;
                }
                let straight_on = touching
                    .iter()
                    .copied()
                    .find(|&e| !used[e] && (p(other_end(e, here)) - p(here)).normalize().dot(&dir) * sign > 1.0 - 1e-9);
                let Some(next) = straight_on else { break };
                used[next] = true;
                ends[end] = other_end(next, here);
            }
        }
        out.push(Segment3 { a: p(ends[0]), b: p(ends[1]) });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::extrude::Extrusion;
    use nalgebra::Point2;

    /// The flag's 6 x 4 checker: 5 lines across and 3 along on each face, each whole.
    #[test]
    fn a_checker_s_markings_are_its_grid_lines_whole() {
        let plate = [[-0.03, -0.02], [0.03, -0.02], [0.03, 0.02], [-0.03, 0.02]].map(|[x, y]| Point2::new(x, y));
        let m = Extrusion::new(plate.to_vec(), 0.004).unwrap().checker_mesh([6, 4], 0.9, 0.0).unwrap();
        let marks = marking_edges(&m, FEATURE_ANGLE_DEG);
        assert_eq!(marks.len(), 2 * (5 + 3), "{marks:?}");
        let across = marks.iter().filter(|s| (s.length() - 0.04).abs() < 1e-12).count();
        let along = marks.iter().filter(|s| (s.length() - 0.06).abs() < 1e-12).count();
        assert_eq!((across, along), (10, 6));
        assert!(marking_edges(&TriMesh::cuboid(Vector3::new(0.01, 0.01, 0.01), 0.5), FEATURE_ANGLE_DEG).is_empty());
    }

    #[test]
    fn a_box_has_twelve_feature_edges_of_the_right_lengths() {
        let m = TriMesh::cuboid(Vector3::new(0.03, 0.02, 0.01), 1.0);
        let edges = feature_edges(&m, FEATURE_ANGLE_DEG);
        assert_eq!(edges.len(), 12);
        let total: f64 = edges.iter().map(Segment3::length).sum();
        assert!((total - 4.0 * (0.06 + 0.04 + 0.02)).abs() < 1e-12);
    }

    #[test]
    fn checker_plate_edges_merge_into_twelve() {
        let sq = [(-0.03, -0.02), (0.03, -0.02), (0.03, 0.02), (-0.03, 0.02)];
        let plate = Extrusion::new(sq.map(|(x, y)| Point2::new(x, y)).to_vec(), 0.004).unwrap();
        let m = plate.checker_mesh([4, 3], 0.9, 0.0).unwrap();
        assert_eq!(feature_edges(&m, FEATURE_ANGLE_DEG).len(), 12);
    }

    #[test]
    fn shallow_folds_are_not_features() {
        // A prism whose profile has a 10 deg bend: the bend's vertical edge is no feature.
        let bend = 10f64.to_radians();
        let prof = vec![
            Point2::new(0.0, 0.0),
            Point2::new(0.05, 0.0),
            Point2::new(0.05 + 0.05 * bend.cos(), 0.05 * bend.sin()),
            Point2::new(0.05 + 0.05 * bend.cos(), 0.05 * bend.sin() + 0.02),
            Point2::new(0.0, 0.02),
        ];
        let m = Extrusion::new(prof, 0.01).unwrap().mesh(1.0);
        let edges = feature_edges(&m, FEATURE_ANGLE_DEG);
        let vertical = edges.iter().filter(|s| s.direction().z.abs() > 0.99).count();
        assert_eq!(vertical, 4, "5 profile corners, one of them too shallow");
    }
}
