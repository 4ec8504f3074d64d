//! Whether a set of views can determine a camera at all, and if not, why: too few views,
//! corners covering too little of the image, or boards all nearly parallel to the image (the
//! focal length is then confounded with the boards' distance).

use nalgebra::{Isometry3, Point2, Vector3};

/// Fewest views per camera: Zhang needs three for the camera matrix; the distortion and a
/// useful covariance want more.
pub const MIN_VIEWS: usize = 6;
/// The image is split into `COVERAGE_GRID`² cells; the corners of all views together must fall
/// in at least [`MIN_COVERAGE`] of them, or the distortion is extrapolated over most of the image.
pub const COVERAGE_GRID: usize = 6;
pub const MIN_COVERAGE: f64 = 0.4;
/// The largest tilt of a board from the image plane, over the views, must reach this (degrees):
/// boards all nearly fronto-parallel leave the focal length undetermined.
pub const MIN_LARGEST_TILT_DEG: f64 = 12.0;

/// Why a set of views cannot calibrate a camera.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Degenerate {
    #[error("{camera} camera: {views} views with the whole board seen; at least {MIN_VIEWS} are needed")]
    TooFewViews { camera: &'static str, views: usize },
    #[error(
        "{camera} camera: the corners cover {:.0}% of the image (cells of a {COVERAGE_GRID}x{COVERAGE_GRID} grid); at least {:.0}% are needed: show the board near the image's edges and corners",
        100.0 * fraction,
        100.0 * MIN_COVERAGE
    )]
    PoorCoverage { camera: &'static str, fraction: f64 },
    #[error(
        "{camera} camera: the boards are all nearly parallel to the image (largest tilt {largest_tilt_deg:.1} deg, at least {MIN_LARGEST_TILT_DEG} deg is needed): tilt the board"
    )]
    FrontoParallel { camera: &'static str, largest_tilt_deg: f64 },
    #[error(
        "{camera} camera: the views' homographies do not determine the camera matrix (Zhang's closed form has no solution): tilt the board in more directions"
    )]
    NoClosedForm { camera: &'static str },
}

/// The fraction of the image's grid cells that hold at least one corner.
pub fn coverage(corners: impl IntoIterator<Item = Point2<f64>>, size: [u32; 2]) -> f64 {
    let mut hit = [[false; COVERAGE_GRID]; COVERAGE_GRID];
    for p in corners {
        let i = ((p.x / size[0] as f64) * COVERAGE_GRID as f64).floor();
        let j = ((p.y / size[1] as f64) * COVERAGE_GRID as f64).floor();
        if (0.0..COVERAGE_GRID as f64).contains(&i) && (0.0..COVERAGE_GRID as f64).contains(&j) {
            hit[j as usize][i as usize] = true;
        }
    }
    hit.iter().flatten().filter(|h| **h).count() as f64 / (COVERAGE_GRID * COVERAGE_GRID) as f64
}

/// A board's tilt from the image plane (degrees): the angle between its normal and the
/// optical axis.
pub fn tilt_deg(cam_from_board: &Isometry3<f64>) -> f64 {
    let normal = cam_from_board.rotation * Vector3::z();
    normal.z.abs().min(1.0).acos().to_degrees()
}
