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
}

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
        serde_json::from_str(&text).map_err(|e| err(format!("line {}: {e}", e.line())))
    }
}
