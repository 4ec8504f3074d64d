//! Tools the gripper holds, from their URDF: a root link (the tool's own frame) and a fixed joint
//! to a link named `grip`, the gripper frame when holding it. The hand-eye calibration flag is
//! `urdf/flag_tool.urdf`.

use crate::arm::{ArmError, origin_pose};
use nalgebra::Isometry3;
use std::path::Path;

/// The link whose frame is the gripper frame while the tool is held.
pub const GRIP_LINK: &str = "grip";

#[derive(Debug, Clone)]
pub struct Tool {
    pub name: String,
    /// The gripper frame in the tool's frame while held.
    pub tool_from_gripper: Isometry3<f64>,
    pub mass: f64,
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
        Ok(Tool {
            name: robot.name.clone(),
            tool_from_gripper: origin_pose(&grip.origin),
            mass: root.inertial.mass.value,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Point3, Vector3};

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
