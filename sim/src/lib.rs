//! The simulated MARVIN cell.
//!
//! - [`world`]: world files (`worlds/*.toml`) and their errors, which name file, line and field.
//! - [`physics`]: the rapier world: fixed boxes, dynamic objects, settling to rest. It knows
//!   nothing of the arm or the scene.
//! - [`arm`]: the URDF arm as a motor-driven multibody with force-limited fingers, in the cell.
//! - [`scene`]: a scenario (world + model library) settled into a [`scene::Scene`]: the fixed
//!   boxes and every object's ground-truth pose; it builds on the cell and the arm.
//! - [`rig`]: the stereo rig of a world as calibrated pinhole cameras.
//! - [`realism`]: the `realism` preset and its effects' specs: lenses, sensors, mountings,
//!   lamps, finishes, the arm as built; the cameras as built ([`realism::RigAsBuilt`]).
//! - [`render`]: the CPU rasteriser: anti-aliased, shaded, noisy 8-bit grey images, with depth
//!   and object-id maps (the ideal preset's renderer as it was), and radiance for the realistic one.
//! - [`lighting`]: lamps with fall-off and soft shadows, sky, gloss, texture.
//! - [`shadows`]: which lamp points a surface point sees: exact shadows on the table's plane,
//!   shadow maps elsewhere.
//! - [`optics`]: lens distortion (a virtual pinhole resampled), depth-dependent blur, vignetting.
//! - [`sensor`]: shot and read noise, fixed patterns, gain, black level, response, 8 bits.
//! - [`imaging`]: the one entry point that renders the cell by its preset.
//! - [`record`]: `scene.json`, the calibration and ground truth written next to the images.
//! - [`shape_mesh`]: colliders' primitives as triangle meshes, to draw the arm.
//! - [`convert`]: nalgebra <-> rapier (glam) conversions, kept in one place.
//!
//! Frames: `world` has its origin at the centre of the table top, `z` up.

pub mod arm;
pub mod convert;
pub mod imaging;
pub mod lighting;
pub mod optics;
pub mod physics;
pub mod realism;
pub mod record;
pub mod render;
pub mod rig;
pub mod scene;
pub mod sensor;
pub mod shadows;
pub mod shape_mesh;
pub mod world;

pub use scene::{Scenario, Scene};
pub use world::WorldFile;
