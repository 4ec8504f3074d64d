//! Tools the gripper holds, from their URDF: a root link (the tool's own frame) and a fixed joint
//! to a link named `grip`, the gripper frame when holding it. The hand-eye calibration flag is
//! `urdf/flag_tool.urdf`. A tool's collision boxes named `locator...` are features that seat it
//! in recesses of the finger pads (the model's own shape has none of them).

use crate::arm::{ArmError, origin_pose};
use nalgebra::{Isometry3, Vector3};
use std::path::Path;

/// The link whose frame is the gripper frame while the tool is held.
pub const GRIP_LINK: &str = "grip";

/// The prefix of the names of a tool's locating features.
pub const LOCATOR_PREFIX: &str = "locator";

/// A box fixed to a tool.
#[derive(Debug, Clone, PartialEq)]
pub struct ToolBox {
    pub tool_from_box: Isometry3<f64>,
    pub half_extents: Vector3<f64>,
}

#[derive(Debug, Clone)]
pub struct Tool {
    pub name: String,
    /// The gripper frame in the tool's frame while held.
    pub tool_from_gripper: Isometry3<f64>,
    pub mass: f64,
    /// Bosses that sit in the finger pads' recesses when the jaws close, so that the tool is held
    /// by its shape across the pads, not by friction alone.
    pub locators: Vec<ToolBox>,
}

impl Tool {
    pub fn from_urdf_file(path: &Path) -> Result<Tool, ArmError> {
        let file = path.display().to_string();
        let err = |message: String| ArmError::Urdf { file: file.clone(), message };
        let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read: {e}")))?;
        let robot = urdf_rs::read_from_string(&text).map_err(|e| err(format!("not valid URDF: {e}")))?;
        let grip = robot
            .joints
            .iter()
            .find(|j| j.child.link == GRIP_LINK && matches!(j.joint_type, urdf_rs::JointType::Fixed))
            .ok_or_else(|| err(format!("a tool needs a fixed joint to a link `{GRIP_LINK}`")))?;
        let root = robot.links.iter().find(|l| l.name == grip.parent.link).expect("urdf-rs checks joint links");
        let locators = root
            .collision
            .iter()
            .filter(|c| c.name.as_deref().is_some_and(|n| n.starts_with(LOCATOR_PREFIX)))
            .map(|c| match &c.geometry {
                urdf_rs::Geometry::Box { size } => Ok(ToolBox {
                    tool_from_box: origin_pose(&c.origin),
                    half_extents: Vector3::new(size[0], size[1], size[2]) / 2.0,
                }),
                _ => Err(err(format!(
                    "link `{}`: collision `{}` must be a box",
                    root.name,
                    c.name.as_deref().unwrap_or_default()
                ))),
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Tool {
            name: robot.name.clone(),
            tool_from_gripper: origin_pose(&grip.origin),
            mass: root.inertial.mass.value,
            locators,
        })
    }

    /// The opening the jaws need to pass over the locators (metres between the pads): twice the
    /// farthest any locator reaches from the gripper's y = 0 plane.
    pub fn locator_clearance(&self) -> f64 {
        let gripper_from_tool = self.tool_from_gripper.inverse();
        let reach = |b: &ToolBox| {
            let gripper_from_box = gripper_from_tool * b.tool_from_box;
            let r = gripper_from_box.rotation.to_rotation_matrix();
            let extent: f64 = (0..3).map(|k| (r[(1, k)] * b.half_extents[k]).abs()).sum();
            gripper_from_box.translation.y.abs() + extent
        };
        2.0 * self.locators.iter().map(reach).fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::arm::{Arm, Primitive};
    use nalgebra::{Point3, Vector3};

    fn urdf(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../urdf").join(name)
    }

    /// Whether two boxes overlap by more than `slack` (metres) on every axis of `b`'s frame (the
    /// tool's and the fingers' boxes are all aligned with the gripper's axes).
    fn overlap(a_pose: &Isometry3<f64>, a_half: &Vector3<f64>, b_pose: &Isometry3<f64>, b_half: &Vector3<f64>) -> bool {
        let b_from_a = b_pose.inverse() * a_pose;
        let centre = b_from_a.translation.vector;
        let r = b_from_a.rotation.to_rotation_matrix();
        (0..3).all(|i| {
            let reach: f64 = (0..3).map(|k| (r[(i, k)] * a_half[k]).abs()).sum();
            (centre[i]).abs() < reach + b_half[i] - 1e-9
        })
    }

    /// The finger boxes, `(base_from_box, half_extents)`, with the jaws at `opening`.
    fn finger_boxes(arm: &Arm, opening: f64) -> Vec<(Isometry3<f64>, Vector3<f64>)> {
        let poses = arm.link_poses(&[0.0; 6], opening);
        arm.finger_joints
            .iter()
            .flat_map(|&j| {
                let link = arm.joints[j].child;
                let base_from_link = poses[link];
                arm.links[link].shapes.iter().map(move |s| match s.primitive {
                    Primitive::Box { half_extents } => (base_from_link * s.link_from_shape, half_extents),
                    _ => panic!("the fingers are boxes"),
                })
            })
            .collect()
    }

    #[test]
    fn the_flags_locators_sit_in_the_pads_recesses_with_no_room_to_slide() {
        let arm = Arm::from_urdf_file(&urdf("umi_rtx.urdf")).unwrap();
        let flag = Tool::from_urdf_file(&urdf("flag_tool.urdf")).unwrap();
        assert_eq!(flag.locators.len(), 4);
        // The jaws must open past the 0.8 mm bosses on both 4 mm faces to take it.
        assert!((flag.locator_clearance() - 0.0056).abs() < 1e-9, "{}", flag.locator_clearance());
        let base_from_tool = arm.link_poses(&[0.0; 6], 0.0)[arm.tcp_link] * flag.tool_from_gripper.inverse();
        let fingers = finger_boxes(&arm, 0.004);
        let hits = |shift: &Vector3<f64>| {
            flag.locators.iter().any(|b| {
                let at = base_from_tool * Isometry3::translation(shift.x, shift.y, shift.z) * b.tool_from_box;
                fingers.iter().any(|(pose, half)| overlap(&at, &b.half_extents, pose, half))
            })
        };
        assert!(!hits(&Vector3::zeros()), "held, the locators touch no finger box");
        // Shifted 0.05 mm along the plate or across it (the pads' plane), or turned, they run into
        // the recesses' walls: the flag is held there by its shape, not by friction.
        for shift in [Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y()] {
            assert!(hits(&(shift * 5e-5)), "shifted by {shift:?} x 0.05 mm the locators are free");
        }
        let turned = |deg: f64| {
            let r = Isometry3::rotation(Vector3::z() * deg.to_radians());
            flag.locators.iter().any(|b| {
                let at = base_from_tool * r * b.tool_from_box;
                fingers.iter().any(|(pose, half)| overlap(&at, &b.half_extents, pose, half))
            })
        };
        assert!(turned(0.3) && turned(-0.3), "turned 0.3 deg in the pads' plane, the locators are free");
    }

    #[test]
    fn the_flag_is_held_by_its_short_edge_across_its_thickness() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../urdf/flag_tool.urdf");
        let flag = Tool::from_urdf_file(&path).unwrap();
        let g = flag.tool_from_gripper;
        // The tool centre point 22 mm from the plate centre towards the -x edge, fingers pointing
        // along +x (into the plate), jaws across z (the 4 mm thickness).
        assert!((g * Point3::origin() - Point3::new(-0.022, 0.0, 0.0)).norm() < 1e-12);
        assert!((g * Vector3::z() - Vector3::x()).norm() < 1e-12);
        assert!((g * Vector3::y()).cross(&Vector3::z()).norm() < 1e-12);
        assert!((flag.mass - 2700.0 * 0.06 * 0.04 * 0.004).abs() < 1e-4);
    }
}
