//! The stereo rig of a world file as calibrated pinhole cameras.

use crate::world::{CameraSpec, RigSpec};
use mesh::{PinholeCamera, StereoCalibration};
use nalgebra::{Point3, Vector3};

pub fn camera(spec: &CameraSpec) -> PinholeCamera {
    let [w, h] = spec.resolution;
    let principal = spec.principal_point.unwrap_or([(w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0]);
    PinholeCamera::looking_at(
        (w, h),
        spec.focal_px,
        principal,
        Point3::from(spec.position_m),
        Point3::from(spec.look_at_m),
        Vector3::from(spec.up),
    )
}

pub fn calibration(rig: &RigSpec) -> StereoCalibration {
    StereoCalibration { left: camera(&rig.left), right: camera(&rig.right) }
}
