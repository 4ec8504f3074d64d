//! Poses as the calibration file and the protocol write them, and rotation-vector helpers.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// `{"translation_m": [x, y, z], "rotation_xyzw": [x, y, z, w]}`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseJson {
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}

impl From<&Isometry3<f64>> for PoseJson {
    fn from(iso: &Isometry3<f64>) -> PoseJson {
        let (t, q) = (iso.translation.vector, iso.rotation.coords);
        PoseJson { translation_m: [t.x, t.y, t.z], rotation_xyzw: [q.x, q.y, q.z, q.w] }
    }
}

impl PoseJson {
    /// Checks that the pose is one: finite, within `max_m` of the origin, its quaternion of unit
    /// norm to 1e-3 (more is a slip, not rounding). Says what is wrong.
    pub fn check(&self, max_m: f64) -> Result<(), String> {
        let t = self.translation_m;
        if !t.iter().all(|v| v.is_finite()) || t.iter().map(|v| v * v).sum::<f64>().sqrt() > max_m {
            return Err(format!("translation_m {t:?} must be finite and within {max_m} m"));
        }
        let norm = self.rotation_xyzw.iter().map(|v| v * v).sum::<f64>().sqrt();
        let unit = (norm - 1.0).abs() <= 1e-3;
        if !unit {
            return Err(format!("rotation_xyzw {:?} is not a unit quaternion (norm {norm})", self.rotation_xyzw));
        }
        Ok(())
    }

    /// The isometry (the quaternion normalised).
    pub fn to_isometry(&self) -> Isometry3<f64> {
        let [x, y, z] = self.translation_m;
        let [qx, qy, qz, qw] = self.rotation_xyzw;
        Isometry3::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_quaternion(Quaternion::new(qw, qx, qy, qz)),
        )
    }
}

/// The rotation by the rotation vector `w` (axis times angle).
pub fn exp(w: &Vector3<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_scaled_axis(*w)
}

/// The rotation vector of `q` (axis times angle, angle in [0, pi]).
pub fn log(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    q.scaled_axis()
}

/// Distance between two poses: translation (metres) and rotation (radians).
pub fn pose_error(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    ((a.translation.vector - b.translation.vector).norm(), a.rotation.angle_to(&b.rotation))
}
