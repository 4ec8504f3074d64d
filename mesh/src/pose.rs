//! How rigid transforms are written in files.
//!
//! A transform `a_from_b` maps coordinates in frame `b` to frame `a`. In JSON and TOML it is
//! `{ "translation_m": [x, y, z], "rotation_xyzw": [x, y, z, w] }` (a unit quaternion), the form
//! [`PoseRecord`] gives; use `#[serde(with = "mesh::pose::iso_serde")]` on an `Isometry3<f64>`.

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

/// A rigid transform as written in files.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseRecord {
    /// Translation in metres.
    pub translation_m: [f64; 3],
    /// Rotation as a unit quaternion, scalar last.
    pub rotation_xyzw: [f64; 4],
}

impl From<&Isometry3<f64>> for PoseRecord {
    fn from(iso: &Isometry3<f64>) -> Self {
        let t = iso.translation.vector;
        let q = iso.rotation.quaternion();
        PoseRecord { translation_m: [t.x, t.y, t.z], rotation_xyzw: [q.i, q.j, q.k, q.w] }
    }
}

impl From<&PoseRecord> for Isometry3<f64> {
    fn from(rec: &PoseRecord) -> Self {
        let [x, y, z, w] = rec.rotation_xyzw;
        let rotation = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
        Isometry3::from_parts(Translation3::from(Vector3::from(rec.translation_m)), rotation)
    }
}

/// How far from 1 a written quaternion's norm may be: six written digits give ~1e-6; a norm
/// further off is a typing slip or another convention, not rounding.
pub const UNIT_TOLERANCE: f64 = 1e-3;

/// Serde adapter for `Isometry3<f64>` fields, through [`PoseRecord`].
pub mod iso_serde {
    use super::{PoseRecord, UNIT_TOLERANCE};
    use nalgebra::Isometry3;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(iso: &Isometry3<f64>, s: S) -> Result<S::Ok, S::Error> {
        PoseRecord::from(iso).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Isometry3<f64>, D::Error> {
        let rec = PoseRecord::deserialize(d)?;
        let norm = rec.rotation_xyzw.iter().map(|c| c * c).sum::<f64>().sqrt();
        let unit = (norm - 1.0).abs() <= UNIT_TOLERANCE;
        if !unit || !rec.translation_m.iter().all(|v| v.is_finite()) {
            return Err(serde::de::Error::custom(format!(
                "rotation_xyzw {:?} is not a unit quaternion (norm {norm:.6}), or translation_m {:?} is not finite",
                rec.rotation_xyzw, rec.translation_m
            )));
        }
        Ok(Isometry3::from(&rec))
    }
}

/// A pose from a position and roll-pitch-yaw angles in degrees (rotation `Rz(yaw) Ry(pitch) Rx(roll)`).
pub fn from_position_rpy_deg(position: [f64; 3], rpy_deg: [f64; 3]) -> Isometry3<f64> {
    let [r, p, y] = rpy_deg.map(f64::to_radians);
    Isometry3::from_parts(Translation3::from(Vector3::from(position)), UnitQuaternion::from_euler_angles(r, p, y))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_record_round_trips() {
        let iso = from_position_rpy_deg([0.1, -0.2, 0.3], [10.0, -20.0, 130.0]);
        let json = serde_json::to_string(&PoseRecord::from(&iso)).unwrap();
        let back: PoseRecord = serde_json::from_str(&json).unwrap();
        let iso2 = Isometry3::from(&back);
        assert!((iso.to_homogeneous() - iso2.to_homogeneous()).norm() < 1e-12);
    }

    #[test]
    fn rpy_is_roll_then_pitch_then_yaw() {
        // Yaw of 90 deg alone turns x into y.
        let iso = from_position_rpy_deg([0.0; 3], [0.0, 0.0, 90.0]);
        let v = iso.rotation * Vector3::x();
        assert!((v - Vector3::y()).norm() < 1e-12);
    }
}
