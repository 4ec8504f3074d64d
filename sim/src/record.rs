//! `scene.json`: the calibration the vision pipeline reads, and the ground truth that only
//! evaluation code may read, written beside the rendered images.

use crate::render::{ARM_ID_BASE, TOOL_ID, arm_link_id};
use crate::scene::{Scenario, Scene};
use mesh::StereoCalibration;
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};

/// Depth maps are 16-bit PNGs in units of this many metres (0.1 mm); 0 means no surface.
pub const DEPTH_UNIT_M: f64 = 1e-4;

/// The contents of `scene.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneRecord {
    pub world: String,
    pub seed: u64,
    /// The world's `realism` preset and the effects in force.
    pub realism: crate::realism::Preset,
    pub effects: crate::realism::Effects,
    /// What the vision pipeline may read: both cameras, `world_from_cam` each, as the world
    /// file gives them (nominal: no lens distortion, the mounting as drawn). In the ideal
    /// preset they are also the truth.
    pub calibration: StereoCalibration,
    /// Ground truth, for evaluation only: the cameras as built (true mounting, lens, sensor).
    /// The depth and id maps are these cameras', pixel for pixel.
    pub as_built: crate::realism::RigAsBuilt,
    /// Ground truth, for evaluation only.
    pub objects: Vec<ObjectRecord>,
    /// The arm's links as the id maps show them (ground truth too: where the arm stood).
    pub arm_links: Vec<LinkRecord>,
    pub depth_unit_m: f64,
    pub id_map: String,
    pub settle: crate::physics::SettleReport,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ObjectRecord {
    /// The value this object has in the id maps.
    pub id: u32,
    pub model: String,
    #[serde(with = "mesh::pose::iso_serde")]
    pub world_from_model: Isometry3<f64>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct LinkRecord {
    pub id: u32,
    /// The URDF link's name.
    pub link: String,
}

impl SceneRecord {
    pub fn new(scn: &Scenario, scene: &Scene, imaging: &crate::imaging::Imaging) -> SceneRecord {
        SceneRecord {
            world: scn.path.display().to_string(),
            seed: scene.seed,
            realism: imaging.preset,
            effects: imaging.effects,
            calibration: imaging.nominal.clone(),
            as_built: imaging.rig.clone(),
            objects: scene
                .objects
                .iter()
                .map(|o| ObjectRecord { id: o.id, model: o.model.clone(), world_from_model: o.world_from_model })
                .collect(),
            arm_links: scene
                .arm
                .iter()
                .enumerate()
                .map(|(k, (link, _))| LinkRecord { id: arm_link_id(k), link: link.clone() })
                .collect(),
            depth_unit_m: DEPTH_UNIT_M,
            id_map: format!(
                "16-bit PNG; each pixel holds the id of what is seen at its centre: objects from 1, the held tool {TOOL_ID}, the arm's links from {ARM_ID_BASE} (arm_links), 0 for the table, floor, bins or nothing"
            ),
            settle: scene.settle,
        }
    }
}
