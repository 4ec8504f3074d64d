//! The stereo rig of a world file: as calibrated pinhole cameras (nominal), and as built.

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

/// The rig as built: each camera's lens, sensor and true mounting, from the world file's specs
/// and `as_built_seed`.
pub fn as_built(rig: &RigSpec, effects: &crate::realism::Effects, as_built_seed: u64) -> crate::realism::RigAsBuilt {
    let (left, right) = (camera(&rig.left), camera(&rig.right));
    fn specs<'a>(spec: &'a CameraSpec, nominal: &'a PinholeCamera) -> crate::realism::CameraSpecs<'a> {
        crate::realism::CameraSpecs {
            nominal,
            lens: spec.lens.as_ref(),
            sensor: spec.sensor.as_ref(),
            mounting: spec.mounting.as_ref(),
        }
    }
    crate::realism::RigAsBuilt::new(specs(&rig.left, &left), specs(&rig.right, &right), effects, as_built_seed)
}
