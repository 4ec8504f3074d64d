//! Tools the gripper holds, from their URDF: a root link (the tool's own frame) and a fixed joint
//! to a link named `grip`, the gripper frame when holding it. The hand-eye calibration flag is
//! `urdf/flag_tool.urdf`. A tool's collision boxes named `locator...` are bosses that seat it in
//! the holes of its jaw inserts, links `insert_left` and `insert_right` clipped onto the finger
//! pads while it is held (the model's own shape has neither).

use crate::arm::{ArmError, origin_pose};
use nalgebra::{Isometry3, Vector3};
use std::path::Path;

/// The link whose frame is the gripper frame while the tool is held.
pub const GRIP_LINK: &str = "grip";

/// The prefix of the names of a tool's locating features.
pub const LOCATOR_PREFIX: &str = "locator";

/// The links of a tool's jaw inserts: on the left finger's pad (+y), on the right's (-y).
pub const INSERT_LINKS: [&str; 2] = ["insert_left", "insert_right"];

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
    /// The jaw inserts' boxes on each finger (`FINGER_JOINTS` order), in the gripper frame as
    /// fitted with the jaws closed on the tool (`ToolBox::tool_from_box` is `gripper_from_box`
    /// here). Empty when the tool has none.
    pub inserts: [Vec<ToolBox>; 2],
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
        let boxes = |link: &urdf_rs::Link, frame: &Isometry3<f64>, pick: &dyn Fn(&str) -> bool| {
            link.collision
                .iter()
                .filter(|c| pick(c.name.as_deref().unwrap_or_default()))
                .map(|c| match &c.geometry {
                    urdf_rs::Geometry::Box { size } => Ok(ToolBox {
                        tool_from_box: frame * origin_pose(&c.origin),
                        half_extents: Vector3::new(size[0], size[1], size[2]) / 2.0,
                    }),
                    _ => Err(err(format!(
                        "link `{}`: collision `{}` must be a box",
                        link.name,
                        c.name.as_deref().unwrap_or_default()
                    ))),
                })
                .collect::<Result<Vec<_>, _>>()
        };
        let locators = boxes(root, &Isometry3::identity(), &|n| n.starts_with(LOCATOR_PREFIX))?;
        let mut inserts: [Vec<ToolBox>; 2] = Default::default();
        for (slot, name) in inserts.iter_mut().zip(INSERT_LINKS) {
            let Some(joint) = robot.joints.iter().find(|j| j.child.link == name) else { continue };
            if joint.parent.link != GRIP_LINK || !matches!(joint.joint_type, urdf_rs::JointType::Fixed) {
                return Err(err(format!("the insert `{name}` must hang from `{GRIP_LINK}` by a fixed joint")));
            }
            let link = robot.links.iter().find(|l| l.name == name).expect("urdf-rs checks joint links");
            *slot = boxes(link, &origin_pose(&joint.origin), &|_| true)?;
        }
        Ok(Tool {
            name: robot.name.clone(),
            tool_from_gripper: origin_pose(&grip.origin),
            mass: root.inertial.mass.value,
            locators,
            inserts,
        })
    }

    /// The opening (metres between the pads) at which the jaws let the tool in: past its
    /// locators and its grasp's width, with room for the inserts.
    pub fn opening_to_take(&self, grasp_opening: f64) -> f64 {
        grasp_opening.max(self.locator_clearance()) + 2.0 * self.insert_thickness()
    }

    /// How far each finger's pad stands from the gripper's y = 0 plane when the jaws hold the
    /// tool on its inserts (metres; 0 without inserts): where the inserts' backs lie.
    pub fn insert_reach(&self) -> f64 {
        let reach = |b: &ToolBox| b.tool_from_box.translation.y.abs() + y_extent(&b.tool_from_box, &b.half_extents);
        self.inserts.iter().flatten().map(reach).fold(0.0, f64::max)
    }

    /// How thick the inserts are along the jaw axis (metres; 0 without inserts).
    pub fn insert_thickness(&self) -> f64 {
        let thickness = |b: &ToolBox| 2.0 * y_extent(&b.tool_from_box, &b.half_extents);
        self.inserts.iter().flatten().map(thickness).fold(0.0, f64::max)
    }

    /// The opening the jaws need to pass over the locators (metres between the pads): twice the
    /// farthest any locator reaches from the gripper's y = 0 plane.
    pub fn locator_clearance(&self) -> f64 {
        let gripper_from_tool = self.tool_from_gripper.inverse();
        let reach = |b: &ToolBox| {
            let gripper_from_box = gripper_from_tool * b.tool_from_box;
            gripper_from_box.translation.y.abs() + y_extent(&gripper_from_box, &b.half_extents)
        };
        2.0 * self.locators.iter().map(reach).fold(0.0, f64::max)
    }
}

/// Half the extent along the gripper's y of a box at `gripper_from_box`.
fn y_extent(gripper_from_box: &Isometry3<f64>, half_extents: &Vector3<f64>) -> f64 {
    let r = gripper_from_box.rotation.to_rotation_matrix();
    (0..3).map(|k| (r[(1, k)] * half_extents[k]).abs()).sum()
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
    fn the_flags_locators_sit_in_its_inserts_holes_with_no_room_to_slide() {
        let arm = Arm::from_urdf_file(&urdf("umi_rtx.urdf")).unwrap();
        let flag = Tool::from_urdf_file(&urdf("flag_tool.urdf")).unwrap();
        assert_eq!(flag.locators.len(), 4);
        assert_eq!(flag.inserts.each_ref().map(|i| i.len()), [5, 5]);
        // 1.5 mm inserts whose faces meet the 4 mm plate: the pads 3.5 mm either side.
        assert!((flag.insert_thickness() - 0.0015).abs() < 1e-9, "{}", flag.insert_thickness());
        assert!((flag.insert_reach() - 0.0035).abs() < 1e-9, "{}", flag.insert_reach());
        // The jaws must open past the 0.8 mm bosses on both faces, and the inserts, to take it.
        assert!((flag.opening_to_take(0.004) - 0.0086).abs() < 1e-9, "{}", flag.opening_to_take(0.004));
        let base_from_gripper = arm.link_poses(&[0.0; 6], 0.0)[arm.tcp_link];
        let base_from_tool = base_from_gripper * flag.tool_from_gripper.inverse();
        let mut solids = finger_boxes(&arm, 2.0 * flag.insert_reach());
        solids.extend(flag.inserts.iter().flatten().map(|b| (base_from_gripper * b.tool_from_box, b.half_extents)));
        let hits = |tool_moved: &Isometry3<f64>| {
            flag.locators.iter().any(|b| {
                let at = base_from_tool * tool_moved * b.tool_from_box;
                solids.iter().any(|(pose, half)| overlap(&at, &b.half_extents, pose, half))
            })
        };
        assert!(!hits(&Isometry3::identity()), "held, the locators touch neither the inserts nor the fingers");
        // Shifted 0.05 mm along the plate or across it (the pads' plane), or turned 0.3 deg in
        // it, they run into the holes' walls: the flag is held there by its shape.
        for shift in [Vector3::x(), -Vector3::x(), Vector3::y(), -Vector3::y()] {
            let moved = shift * 5e-5;
            assert!(hits(&Isometry3::translation(moved.x, moved.y, moved.z)), "shifted along {shift:?}: free");
        }
        for deg in [0.3, -0.3] {
            assert!(hits(&Isometry3::rotation(Vector3::z() * f64::to_radians(deg))), "turned {deg} deg: free");
        }
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
