//! The emulated MARVIN/TINA vision pipeline. It sees images, a stereo calibration
//! ([`mesh::StereoCalibration`]) and the model library, never the simulation.
//!
//! - [`image`]: grey images as plain data.
//! - [`canny`]: Canny edges (sigma 1, separable Gaussian) located to sub-pixel acuity.
//! - [`strings`]: edgels linked into ordered 8-connected edge strings.
//! - [`rectify`]: edge locations mapped into a parallel-camera geometry (rows are epipolars).
//! - [`pmf`]: PMF stereo matching of rectified edgels.
//!
//! Still to come (the front-end issue): 2D and 3D lines, slices and the Joiner; then the model
//! matcher.

pub mod canny;
pub mod image;
pub mod pmf;
pub mod rectify;
pub mod strings;

pub use canny::{CannyParams, EdgeMap, Edgel, canny};
pub use image::GreyImage;
pub use strings::{EdgeString, link_strings};
