//! Camera calibration from a checkerboard, as TINA calibrated its cameras from a tile: both
//! cameras' intrinsics and lens distortion and the rig (the right camera's pose in the left's)
//! measured from views of a board, never read from the renderer.
//!
//! - [`board`]: the board's geometry: its inner corners in its own frame.
//! - [`camera`]: a camera's intrinsics (`fx fy cx cy`, `plumb_bob` distortion) and projection.
//! - [`detect`]: the board's corners in an image, labelled and refined to sub-pixel, or why a
//!   view is dropped (board not found, partly out of view, too blurred, too oblique).
//! - [`zhang`]: the closed-form start: homographies, the camera matrix, the board poses.
//! - [`checks`]: whether views can determine a camera: enough of them, corners over enough of
//!   the image, boards tilted enough.
//! - [`adjust`]: the joint Levenberg-Marquardt adjustment with a robust (Huber) loss, and the
//!   parameters' covariance.
//! - [`solve`]: the whole routine for a stereo pair, per-view reprojection RMS, sigmas.
//! - [`file`]: the calibration files: the project's JSON (with covariances) and a ROS
//!   `camera_info` YAML per camera, with the stereo rectification (`R`, `P`) they carry.

pub mod adjust;
pub mod board;
pub mod camera;
pub mod checks;
pub mod detect;
pub mod file;
pub mod solve;
pub mod zhang;

pub use board::Board;
pub use camera::Intrinsics;
pub use solve::{CalibrationError, Options, StereoSolution, ViewCorners, calibrate_stereo};
