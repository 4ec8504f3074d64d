//! The simulated MARVIN cell.
//!
//! - [`world`]: world files (`worlds/*.toml`) and their errors, which name file, line and field.
//! - [`physics`]: the rapier world: fixed boxes, dynamic objects, settling to rest. It knows
//!   nothing of the arm or the scene.
//! - [`arm`]: the URDF arm as a motor-driven multibody with force-limited fingers, in the cell.
//! - [`scene`]: a scenario (world + model library) settled into a [`scene::Scene`]: the fixed
//!   boxes and every object's ground-truth pose; it builds on the cell and the arm.
//! - [`rig`]: the stereo rig of a world as calibrated pinhole cameras.
//! - [`render`]: the CPU renderer: anti-aliased, shaded, noisy 8-bit grey images, with depth
//!   and object-id maps.
//! - [`record`]: `scene.json`, the calibration and ground truth written next to the images.
//! - [`shape_mesh`]: colliders' primitives as triangle meshes, to draw the arm.
//! - [`convert`]: nalgebra <-> rapier (glam) conversions, kept in one place.
//!
//! Frames: `world` has its origin at the centre of the table top, `z` up.

pub mod arm;
pub mod convert;
pub mod physics;
pub mod record;
pub mod render;
pub mod rig;
pub mod scene;
pub mod shape_mesh;
pub mod world;

pub use scene::{Scenario, Scene};
pub use world::WorldFile;
