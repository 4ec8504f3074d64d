//! The calibration file (`out/hand_eye.json` by default): what `marvin calibrate` writes and
//! `marvin serve --hand-eye FILE` (and the `set_hand_eye` request) take.

use crate::pose::PoseJson;
use crate::refine::PARAMS;
use crate::solve::{Sigmas, Solution};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The order of the covariance's rows and columns.
pub const COVARIANCE_ORDER: &str =
    "cam_from_base rotation vector (rad, applied on the left) x y z, translation (m) x y z; gripper_from_flag the same";

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandEyeFile {
    pub cam_from_base: PoseJson,
    pub gripper_from_flag: PoseJson,
    /// 12 x 12, row by row, in [`COVARIANCE_ORDER`].
    pub covariance: Vec<Vec<f64>>,
    pub covariance_order: String,
    pub sigma: Sigmas,
    pub residual_mm_rms: f64,
    pub residual_deg_rms: f64,
    pub sightings_used: usize,
    pub sightings_total: usize,
    /// Why each dropped sighting was dropped.
    pub dropped: Vec<String>,
}

/// Why a calibration file could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum FileError {
    #[error("{path}: {message}")]
    Io { path: String, message: String },
    #[error("{path}: field `{field}`: {message}")]
    Invalid { path: String, field: String, message: String },
}

/// Farthest a calibrated transform may reach, metres: the cell is a few metres across.
const MAX_REACH_M: f64 = 100.0;

impl HandEyeFile {
    pub fn from_solution(s: &Solution) -> HandEyeFile {
        HandEyeFile {
            cam_from_base: PoseJson::from(&s.cam_from_base),
            gripper_from_flag: PoseJson::from(&s.gripper_from_flag),
            covariance: (0..PARAMS).map(|r| (0..PARAMS).map(|c| s.covariance[(r, c)]).collect()).collect(),
            covariance_order: COVARIANCE_ORDER.into(),
            sigma: s.sigma,
            residual_mm_rms: s.residual_mm_rms,
            residual_deg_rms: s.residual_deg_rms,
            sightings_used: s.used.iter().filter(|u| **u).count(),
            sightings_total: s.used.len(),
            dropped: s.dropped.iter().map(|(_, why)| why.clone()).collect(),
        }
    }

    pub fn save(&self, path: &Path) -> Result<(), FileError> {
        let err = |message: String| FileError::Io { path: path.display().to_string(), message };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(|e| err(format!("cannot create its folder: {e}")))?;
        }
        let text = serde_json::to_string_pretty(self).expect("the file serialises");
        std::fs::write(path, text + "\n").map_err(|e| err(format!("cannot write: {e}")))
    }

    pub fn load(path: &Path) -> Result<HandEyeFile, FileError> {
        let err = |message: String| FileError::Io { path: path.display().to_string(), message };
        let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
        let file: HandEyeFile = serde_json::from_str(&text).map_err(|e| err(format!("line {}: {e}", e.line())))?;
        for (field, pose) in [("cam_from_base", &file.cam_from_base), ("gripper_from_flag", &file.gripper_from_flag)] {
            pose.check(MAX_REACH_M).map_err(|message| FileError::Invalid {
                path: path.display().to_string(),
                field: field.into(),
                message,
            })?;
        }
        Ok(file)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> HandEyeFile {
        let pose = PoseJson { translation_m: [0.1, -0.2, 0.9], rotation_xyzw: [0.0, 0.0, 0.0, 1.0] };
        HandEyeFile {
            cam_from_base: pose,
            gripper_from_flag: pose,
            covariance: vec![vec![0.0; PARAMS]; PARAMS],
            covariance_order: COVARIANCE_ORDER.into(),
            sigma: Sigmas {
                cam_from_base_deg: 0.01,
                cam_from_base_mm: 0.1,
                gripper_from_flag_deg: 0.01,
                gripper_from_flag_mm: 0.1,
            },
            residual_mm_rms: 0.1,
            residual_deg_rms: 0.01,
            sightings_used: 20,
            sightings_total: 20,
            dropped: Vec::new(),
        }
    }

    #[test]
    fn a_file_round_trips_and_a_pose_that_is_none_is_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("hand_eye_file_{}", std::process::id()));
        let path = dir.join("he.json");
        file().save(&path).unwrap();
        assert_eq!(HandEyeFile::load(&path).unwrap(), file());
        let mut stretched = file();
        stretched.cam_from_base.rotation_xyzw = [0.0, 0.0, 0.0, 2.0];
        let mut far = file();
        far.gripper_from_flag.translation_m = [1e9, 0.0, 0.0];
        for (bad, field, says) in
            [(stretched, "cam_from_base", "unit quaternion"), (far, "gripper_from_flag", "within")]
        {
            bad.save(&path).unwrap();
            let e = HandEyeFile::load(&path).unwrap_err().to_string();
            assert!(e.contains("he.json") && e.contains(field) && e.contains(says), "{e}");
        }
        std::fs::remove_dir_all(dir).unwrap();
    }
}
