//! The emulated MARVIN/TINA vision pipeline. It sees images, a stereo calibration
//! ([`mesh::StereoCalibration`]) and the model library, never the simulation.
//!
//! - [`image`]: grey images as plain data.
//! - [`canny`](mod@canny): Canny edges (sigma 1, separable Gaussian) located to sub-pixel acuity.
//! - [`strings`]: edgels linked into ordered 8-connected edge strings.
//! - [`rectify`]: edge locations mapped into a parallel-camera geometry (rows are epipolars).
//! - [`pmf`]: PMF stereo matching of rectified edgels.
//! - [`lines2d`]: strings cut into straight lines by recursive fit and segment.
//! - [`lines3d`]: disparity fitted along each 2D line, its ends triangulated into 3D segments.
//! - [`front_end`]: the stages above run in order on one stereo pair.
//! - [`slices`]: the same cut into 8 horizontal slice pairs run in parallel, and the Joiner.
//! - [`pose_fit`]: least-squares pose from 3D line correspondences (quaternion method).
//! - [`matcher`]: the model matcher (pairwise relations, focus features in characteristic
//!   views, hypotheses ranked by support, refinement, verification), all models in parallel.
//! - [`support`]: the support a pose finds among the scene lines, as the matcher counts it.
//! - [`verify`]: verification of a located model against the edgels of the left image.
//! - [`occlusion`]: located solids (and a model's own bulk) hiding parts of a wireframe.
//! - [`image_fit`]: pose refinement on the left image's edgels and the 3D lines together.
//! - [`second_look`]: objects with too few 3D lines, from one 3D line and an image line
//!   meeting it at a corner.
//!
//! Still to come: the runtime of communicating processes.

pub mod canny;
pub mod front_end;
pub mod image;
pub mod image_fit;
pub mod lines2d;
pub mod lines3d;
pub mod matcher;
pub mod occlusion;
pub mod pmf;
pub mod pose_fit;
pub mod rectify;
pub mod second_look;
pub mod slices;
pub mod strings;
pub mod support;
pub mod verify;

pub use canny::{CannyParams, EdgeMap, Edgel, canny};
pub use image::GreyImage;
pub use strings::{EdgeString, link_strings};

/// What the unit tests of several stages set up alike.
#[cfg(test)]
pub(crate) mod fixtures {
    use crate::matcher::MatcherModel;
    use mesh::PinholeCamera;
    use nalgebra::{Point3, Vector3};

    /// A library model as the matcher holds it.
    pub(crate) fn model(name: &str) -> MatcherModel {
        let lib = mesh::Library::load_default().unwrap();
        MatcherModel::from_model(lib.get(name).unwrap_or_else(|| panic!("no model `{name}` in the library")))
    }

    /// A 512x512 camera of 1000 px focal length at `eye`, looking at the world's origin, `z` up.
    pub(crate) fn camera_at(eye: Point3<f64>) -> PinholeCamera {
        PinholeCamera::looking_at((512, 512), 1000.0, [255.5, 255.5], eye, Point3::origin(), Vector3::z())
    }
}
