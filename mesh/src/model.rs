//! A library model: the TOML a person writes ([`ModelSpec`]) and everything built from it
//! ([`Model`]).
//!
//! Gripper frame of a grasp: origin at the tool centre point between the fingertips, `z` the
//! approach direction (from the gripper into the object), `y` the axis along which the jaws
//! close. `opening_mm` is the object's width between the jaws at the grasp.

use crate::extrude::Extrusion;
use crate::mass::{MassProperties, mass_properties};
use crate::pose::from_position_rpy_deg;
use crate::trimesh::TriMesh;
use crate::wireframe::{FEATURE_ANGLE_DEG, Segment3, feature_edges, marking_edges};
use nalgebra::{Isometry3, Point2, Point3};
use serde::Deserialize;
use std::path::Path;

/// A model file, `mesh/models/<name>.toml`. Lengths in millimetres.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelSpec {
    pub name: String,
    #[serde(default)]
    pub description: String,
    pub density_kg_m3: f64,
    /// Diffuse reflectance, 0-1.
    pub albedo: f64,
    /// How glossy the surface is, for the realistic renderer only (the matcher never reads it).
    #[serde(default)]
    pub finish: FinishSpec,
    pub shape: ShapeSpec,
    #[serde(default)]
    pub grasps: Vec<GraspSpec>,
}

/// A surface's gloss: `specular` is the fraction of light reflected glossily (the rest
/// diffusely, times the albedo), `roughness` how wide the highlight is (0 a mirror, 1 nearly
/// diffuse). Left out: a matte plastic's 0.04 and 0.5.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FinishSpec {
    #[serde(default = "default_specular")]
    pub specular: f64,
    #[serde(default = "default_roughness")]
    pub roughness: f64,
}

fn default_specular() -> f64 {
    0.04
}

fn default_roughness() -> f64 {
    0.5
}

impl Default for FinishSpec {
    fn default() -> Self {
        FinishSpec { specular: default_specular(), roughness: default_roughness() }
    }
}

/// How a model's solid is given.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ShapeSpec {
    /// A simple polygon in the model's `xy` plane extruded symmetrically along `z`.
    Extrusion {
        profile_mm: Vec<[f64; 2]>,
        thickness_mm: f64,
        /// Checker squares `[nx, ny]` on both caps (rectangular profiles only).
        checker: Option<[u32; 2]>,
        /// A plain border around the checker, millimetres (a calibration board's quiet zone).
        #[serde(default)]
        checker_margin_mm: f64,
    },
    /// A closed Wavefront OBJ mesh, path relative to the model file, coordinates in millimetres.
    Obj { file: String },
}

/// A grasp as written: gripper pose in the model frame and the jaw opening.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GraspSpec {
    pub position_mm: [f64; 3],
    pub rpy_deg: [f64; 3],
    pub opening_mm: f64,
}

/// A grasp position: where the gripper centre goes, in the model frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grasp {
    pub model_from_gripper: Isometry3<f64>,
    /// Object width between the jaws, metres.
    pub opening: f64,
}

/// How the physics engine should see the solid.
#[derive(Debug, Clone, PartialEq)]
pub enum Collision {
    /// An exact decomposition: the union of the convex hulls of these point sets.
    ConvexPieces(Vec<Vec<Point3<f64>>>),
    /// A non-convex mesh the physics side must decompose itself (approximately).
    Decompose,
}

/// A built library model.
#[derive(Debug, Clone)]
pub struct Model {
    pub name: String,
    pub description: String,
    pub mesh: TriMesh,
    /// The surface's gloss, for rendering.
    pub finish: FinishSpec,
    pub collision: Collision,
    pub wireframe: Vec<Segment3>,
    /// Lines of the surface's pattern (the flag's checker), seen as edges though no solid edge
    /// lies there; empty for plain parts.
    pub markings: Vec<Segment3>,
    pub mass: MassProperties,
    pub grasps: Vec<Grasp>,
}

const MM: f64 = 1e-3;

impl Model {
    /// Builds a model; `dir` resolves an OBJ file's relative path.
    pub fn build(spec: &ModelSpec, dir: &Path) -> Result<Model, String> {
        if !(0.0..=1.0).contains(&spec.albedo) {
            return Err(format!("albedo must be within 0-1, got {}", spec.albedo));
        }
        if spec.density_kg_m3.is_nan() || spec.density_kg_m3 <= 0.0 {
            return Err(format!("density_kg_m3 must be positive, got {}", spec.density_kg_m3));
        }
        let f = spec.finish;
        if !((0.0..=1.0).contains(&f.specular) && (0.02..=1.0).contains(&f.roughness)) {
            return Err(format!(
                "finish: specular must be within 0-1 and roughness within 0.02-1, got {} and {}",
                f.specular, f.roughness
            ));
        }
        let albedo = spec.albedo as f32;
        let (mesh, collision) = match &spec.shape {
            ShapeSpec::Extrusion { profile_mm, thickness_mm, checker, checker_margin_mm } => {
                let profile = profile_mm.iter().map(|&[x, y]| Point2::new(x * MM, y * MM)).collect();
                let ext = Extrusion::new(profile, thickness_mm * MM).map_err(|e| format!("shape: {e}"))?;
                let mesh = match checker {
                    Some(n) => ext
                        .checker_mesh(*n, albedo, checker_margin_mm * MM)
                        .map_err(|e| format!("shape.checker: {e}"))?,
                    None => ext.mesh(albedo),
                };
                (mesh, Collision::ConvexPieces(ext.convex_pieces()))
            }
            ShapeSpec::Obj { file } => {
                let path = dir.join(file);
                let mesh =
                    crate::obj::load(&path, MM, albedo).map_err(|e| format!("shape.file {}: {e}", path.display()))?;
                let collision = if crate::obj::is_convex(&mesh, 1e-9) {
                    Collision::ConvexPieces(vec![mesh.vertices.clone()])
                } else {
                    Collision::Decompose
                };
                (mesh, collision)
            }
        };
        let grasps = spec
            .grasps
            .iter()
            .map(|g| Grasp {
                model_from_gripper: from_position_rpy_deg(g.position_mm.map(|c| c * MM), g.rpy_deg),
                opening: g.opening_mm * MM,
            })
            .collect();
        Ok(Model {
            name: spec.name.clone(),
            description: spec.description.clone(),
            wireframe: feature_edges(&mesh, FEATURE_ANGLE_DEG),
            markings: marking_edges(&mesh, FEATURE_ANGLE_DEG),
            mass: mass_properties(&mesh, spec.density_kg_m3),
            collision,
            mesh,
            finish: spec.finish,
            grasps,
        })
    }

    /// Size of the model's bounding box, metres.
    pub fn extent(&self) -> nalgebra::Vector3<f64> {
        let (lo, hi) = self.mesh.bounds().expect("a built model has vertices");
        hi - lo
    }
}

/// The rotations that map a model onto itself (about its centre of mass): found by trying turns
/// of 1/2, 1/3, 1/4 and 1/6 about its principal axes and keeping those that carry every
/// wireframe edge onto an edge. Always holds the identity.
pub fn symmetries(model: &Model) -> Vec<nalgebra::Isometry3<f64>> {
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
    let c = model.mass.centre_of_mass;
    let axes = model.mass.inertia.symmetric_eigen().eigenvectors;
    let about = |r: UnitQuaternion<f64>| Translation3::from(c.coords) * r * Translation3::from(-c.coords);
    let maps_onto_itself = |g: &Isometry3<f64>| {
        model.wireframe.iter().all(|s| {
            let (a, b) = (g * s.a, g * s.b);
            model.wireframe.iter().any(|t| {
                ((a - t.a).norm() < 1e-4 && (b - t.b).norm() < 1e-4)
                    || ((a - t.b).norm() < 1e-4 && (b - t.a).norm() < 1e-4)
            })
        })
    };
    let mut out = vec![Isometry3::identity()];
    for k in 0..3 {
        let axis = nalgebra::Unit::new_normalize(Vector3::from(axes.column(k)));
        for n in [2u32, 3, 4, 6] {
            for m in 1..n {
                let g = about(UnitQuaternion::from_axis_angle(&axis, std::f64::consts::TAU * m as f64 / n as f64));
                let new = out.iter().all(|h| (h.to_homogeneous() - g.to_homogeneous()).norm() > 1e-6);
                if new && maps_onto_itself(&g) {
                    out.push(g);
                }
            }
        }
    }
    // Products of the turns found (e.g. 180 deg about two axes give the third).
    let found = out.clone();
    for a in &found {
        for b in &found {
            let g = a * b;
            if out.iter().all(|h| (h.to_homogeneous() - g.to_homogeneous()).norm() > 1e-6) && maps_onto_itself(&g) {
                out.push(g);
            }
        }
    }
    out
}
