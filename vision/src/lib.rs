//! The emulated MARVIN/TINA vision pipeline. It sees images, a stereo calibration
//! ([`mesh::StereoCalibration`]) and the model library, never the simulation.
//!
//! MARVIN's two phases, one folder each:
//!
//! - [`front_end`]: scene geometry from stereo. Canny (sigma 1, sub-pixel, edgels beside
//!   narrow faces deblurred), edge strings, rectified edge locations, PMF stereo, 2D lines, 3D
//!   lines; on the whole image or in 8 slices run in parallel and joined.
//! - [`matcher`]: model matching. Characteristic views and their pairwise tables, hypotheses
//!   ranked by support, verification against the left image, refinement, the looks for objects
//!   with too few 3D lines or partly hidden, all models in parallel.
//!
//! and what both take:
//!
//! - [`image`]: grey images as plain data, and the nearest pixel to a point.
//!
//! The matcher takes the front end's output types; the front end imports nothing of the
//! matcher. Still to come: the runtime of communicating processes.

pub mod front_end;
pub mod image;
pub mod matcher;

pub use front_end::canny::{CannyParams, EdgeMap, Edgel, canny};
pub use front_end::strings::{EdgeString, link_strings};
pub use image::GreyImage;
