//! The object library of MARVIN, and the geometry every other crate shares.
//!
//! - [`model`]: a library model as written in `mesh/models/*.toml` ([`model::ModelSpec`]) and as
//!   built ([`model::Model`]): render mesh, collision pieces, wireframe, mass, grasp positions.
//! - [`library`]: loads every model file of a folder into a [`library::Library`].
//! - [`trimesh`]: indexed triangle meshes with face normals and per-face albedo.
//! - [`polygon`]: 2D profiles: ear-clipping triangulation and exact convex decomposition.
//! - [`extrude`]: extruded-profile models (optionally with a checker pattern, for the flag).
//! - [`obj`]: Wavefront OBJ models.
//! - [`wireframe`]: straight feature edges (adjacent faces meeting at >= 20 deg), what the
//!   model matcher sees of a model.
//! - [`mass`]: volume, centre of mass and inertia of a closed mesh at a density.
//! - [`camera`]: the pinhole camera and the stereo calibration file the vision pipeline reads.
//! - [`distortion`]: lens distortion in the OpenCV/ROS `plumb_bob` model, and its inverse.
//! - [`pose`]: how transforms are written in files (`a_from_b`, metres, quaternions).
//!
//! Units are metres, radians and kilograms inside; model files are written in millimetres.

pub mod camera;
pub mod distortion;
pub mod extrude;
pub mod library;
pub mod mass;
pub mod model;
pub mod obj;
pub mod polygon;
pub mod pose;
pub mod trimesh;
pub mod wireframe;

pub use camera::{LensCamera, PinholeCamera, StereoCalibration};
pub use library::Library;
pub use model::{Grasp, Model, ModelSpec};
pub use trimesh::TriMesh;
pub use wireframe::Segment3;
