//! The arm as its URDF describes it: links with their collision shapes, joints with their
//! limits, and forward kinematics over the link tree.
//!
//! The arm joints are addressed by name (`ARM_JOINTS`); a configuration is a [`Joints`] vector in
//! that order (zed in metres, the rest in radians). The two fingers always move together: the
//! gripper's `opening` (metres between the pads) puts each finger at half of it.

use nalgebra::{Isometry3, Point3, Translation3, Unit, UnitQuaternion, Vector3};
use std::collections::HashMap;
use std::path::Path;

/// The arm joints, in the order of a [`Joints`] vector.
pub const ARM_JOINTS: [&str; 6] = ["zed", "shoulder", "elbow", "wrist_yaw", "wrist_pitch", "wrist_roll"];
/// The finger joints; each travels half the gripper opening.
pub const FINGER_JOINTS: [&str; 2] = ["finger_left", "finger_right"];
/// The link whose frame is the gripper frame (tool centre point, z approach, y jaw axis).
pub const TCP_LINK: &str = "tcp";
/// URDF has no acceleration limits; each joint may reach its velocity limit in this long.
pub const TIME_TO_FULL_SPEED_S: f64 = 0.25;

/// A configuration of the arm joints, in [`ARM_JOINTS`] order.
pub type Joints = [f64; 6];

#[derive(Debug, thiserror::Error)]
pub enum ArmError {
    #[error("{file}: {message}")]
    Urdf { file: String, message: String },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    Revolute,
    Prismatic,
    Fixed,
}

/// One URDF joint.
#[derive(Debug, Clone)]
pub struct JointSpec {
    pub name: String,
    pub kind: JointKind,
    pub parent: usize,
    pub child: usize,
    /// The joint frame in the parent link's frame (the URDF `<origin>`).
    pub parent_from_joint: Isometry3<f64>,
    pub axis: Unit<Vector3<f64>>,
    pub lower: f64,
    pub upper: f64,
    pub max_velocity: f64,
    /// Newtons or newton-metres; for the fingers, the grip force limit.
    pub max_effort: f64,
}

/// A primitive collision shape of a link.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Primitive {
    Box {
        half_extents: Vector3<f64>,
    },
    /// Axis along the shape frame's z, as in URDF.
    Cylinder {
        radius: f64,
        half_length: f64,
    },
    Sphere {
        radius: f64,
    },
    /// Axis along the shape frame's z.
    Capsule {
        radius: f64,
        half_length: f64,
    },
}

#[derive(Debug, Clone)]
pub struct LinkShape {
    pub link_from_shape: Isometry3<f64>,
    pub primitive: Primitive,
}

#[derive(Debug, Clone)]
pub struct LinkSpec {
    pub name: String,
    pub mass: f64,
    pub shapes: Vec<LinkShape>,
}

/// The arm model.
#[derive(Debug, Clone)]
pub struct Arm {
    pub name: String,
    pub links: Vec<LinkSpec>,
    pub joints: Vec<JointSpec>,
    /// Joint indices of [`ARM_JOINTS`].
    pub arm_joints: [usize; 6],
    pub finger_joints: [usize; 2],
    pub tcp_link: usize,
    /// Joints ordered so that every parent link is placed before its children.
    order: Vec<usize>,
}

impl Arm {
    pub fn from_urdf_file(path: &Path) -> Result<Arm, ArmError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| ArmError::Urdf { file: file.clone(), message: format!("cannot read: {e}") })?;
        Arm::from_urdf_str(&text, &file)
    }

    /// Parses URDF text; `file` names it in errors.
    pub fn from_urdf_str(text: &str, file: &str) -> Result<Arm, ArmError> {
        let err = |message: String| ArmError::Urdf { file: file.to_string(), message };
        let robot = urdf_rs::read_from_string(text).map_err(|e| err(format!("not valid URDF: {e}")))?;
        let link_index: HashMap<&str, usize> =
            robot.links.iter().enumerate().map(|(i, l)| (l.name.as_str(), i)).collect();
        let links = robot.links.iter().map(link_spec).collect::<Result<Vec<_>, String>>().map_err(err)?;
        let mut joints = Vec::new();
        for j in &robot.joints {
            let find = |name: &str| {
                link_index.get(name).copied().ok_or_else(|| err(format!("joint `{}`: no link `{name}`", j.name)))
            };
            joints.push(joint_spec(j, find(&j.parent.link)?, find(&j.child.link)?).map_err(err)?);
        }
        let joint_named = |name: &str| {
            joints.iter().position(|j| j.name == name).ok_or_else(|| err(format!("the arm needs a joint `{name}`")))
        };
        let mut arm_joints = [0; 6];
        for (slot, name) in arm_joints.iter_mut().zip(ARM_JOINTS) {
            *slot = joint_named(name)?;
        }
        let finger_joints = [joint_named(FINGER_JOINTS[0])?, joint_named(FINGER_JOINTS[1])?];
        let tcp_link = *link_index.get(TCP_LINK).ok_or_else(|| err(format!("the arm needs a link `{TCP_LINK}`")))?;
        let order = root_to_leaf_order(&joints, links.len()).map_err(err)?;
        Ok(Arm { name: robot.name.clone(), links, joints, arm_joints, finger_joints, tcp_link, order })
    }

    pub fn joint(&self, k: usize) -> &JointSpec {
        &self.joints[self.arm_joints[k]]
    }

    pub fn lower(&self) -> Joints {
        std::array::from_fn(|k| self.joint(k).lower)
    }

    pub fn upper(&self) -> Joints {
        std::array::from_fn(|k| self.joint(k).upper)
    }

    pub fn max_velocity(&self) -> Joints {
        std::array::from_fn(|k| self.joint(k).max_velocity)
    }

    pub fn max_acceleration(&self) -> Joints {
        std::array::from_fn(|k| self.joint(k).max_velocity / TIME_TO_FULL_SPEED_S)
    }

    /// The widest opening the fingers allow, metres.
    pub fn max_opening(&self) -> f64 {
        self.finger_joints.iter().map(|&j| self.joints[j].upper).sum()
    }

    /// The first arm joint outside its limits, with its value, if any.
    pub fn limit_violation(&self, q: &Joints) -> Option<(usize, f64)> {
        (0..6).find(|&k| q[k] < self.joint(k).lower - 1e-12 || q[k] > self.joint(k).upper + 1e-12).map(|k| (k, q[k]))
    }

    /// `base_from_link` for every link.
    pub fn link_poses(&self, q: &Joints, opening: f64) -> Vec<Isometry3<f64>> {
        let mut values = vec![0.0; self.joints.len()];
        for (k, &j) in self.arm_joints.iter().enumerate() {
            values[j] = q[k];
        }
        for &j in &self.finger_joints {
            values[j] = opening / 2.0;
        }
        let mut poses = vec![Isometry3::identity(); self.links.len()];
        for &j in &self.order {
            let joint = &self.joints[j];
            poses[joint.child] = poses[joint.parent] * joint.parent_from_joint * joint_motion(joint, values[j]);
        }
        poses
    }

    /// How far the fingertips reach beyond the tool centre point along its z (the approach),
    /// metres: the furthest corner of the finger links' collision shapes, from the URDF.
    pub fn fingertip_reach(&self) -> f64 {
        let poses = self.link_poses(&[0.0; 6], 0.0);
        let tcp_from_base = poses[self.tcp_link].inverse();
        let fingers = self.finger_joints.iter().map(|&j| self.joints[j].child);
        fingers
            .flat_map(|link| self.links[link].shapes.iter().map(move |s| (link, s)))
            .flat_map(|(link, s)| {
                let tcp_from_shape = tcp_from_base * poses[link] * s.link_from_shape;
                shape_corners(&s.primitive).into_iter().map(move |c| (tcp_from_shape * c).z)
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// Forward kinematics: the gripper (tool centre point) frame in the base frame.
    pub fn base_from_gripper(&self, q: &Joints) -> Isometry3<f64> {
        self.link_poses(q, 0.0)[self.tcp_link]
    }
}

/// The corners of a primitive's bounding box in its own frame (exact for boxes, which the
/// fingers are; a bound for the rest).
fn shape_corners(p: &Primitive) -> Vec<Point3<f64>> {
    let half = match *p {
        Primitive::Box { half_extents } => half_extents,
        Primitive::Cylinder { radius, half_length } => Vector3::new(radius, radius, half_length),
        Primitive::Sphere { radius } => Vector3::repeat(radius),
        Primitive::Capsule { radius, half_length } => Vector3::new(radius, radius, half_length + radius),
    };
    (0..8)
        .map(|k| {
            let sign = |bit: usize| if k & bit == 0 { -1.0 } else { 1.0 };
            Point3::new(sign(1) * half.x, sign(2) * half.y, sign(4) * half.z)
        })
        .collect()
}

fn joint_motion(joint: &JointSpec, value: f64) -> Isometry3<f64> {
    match joint.kind {
        JointKind::Revolute => {
            Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&joint.axis, value))
        }
        JointKind::Prismatic => {
            Isometry3::from_parts(Translation3::from(joint.axis.into_inner() * value), UnitQuaternion::identity())
        }
        JointKind::Fixed => Isometry3::identity(),
    }
}

/// A URDF `<origin>` as an isometry: rpy are fixed-axis roll, pitch, yaw (Rz·Ry·Rx).
pub fn origin_pose(pose: &urdf_rs::Pose) -> Isometry3<f64> {
    let [x, y, z] = pose.xyz.0;
    let [roll, pitch, yaw] = pose.rpy.0;
    Isometry3::from_parts(Translation3::new(x, y, z), UnitQuaternion::from_euler_angles(roll, pitch, yaw))
}

fn link_spec(link: &urdf_rs::Link) -> Result<LinkSpec, String> {
    let shapes = link
        .collision
        .iter()
        .map(|c| {
            let primitive = match &c.geometry {
                urdf_rs::Geometry::Box { size } => {
                    Primitive::Box { half_extents: Vector3::new(size[0], size[1], size[2]) / 2.0 }
                }
                urdf_rs::Geometry::Cylinder { radius, length } => {
                    Primitive::Cylinder { radius: *radius, half_length: length / 2.0 }
                }
                urdf_rs::Geometry::Capsule { radius, length } => {
                    Primitive::Capsule { radius: *radius, half_length: length / 2.0 }
                }
                urdf_rs::Geometry::Sphere { radius } => Primitive::Sphere { radius: *radius },
                urdf_rs::Geometry::Mesh { filename, .. } => {
                    return Err(format!(
                        "link `{}`: mesh collision `{filename}`: the arm takes primitive collision shapes only",
                        link.name
                    ));
                }
            };
            Ok(LinkShape { link_from_shape: origin_pose(&c.origin), primitive })
        })
        .collect::<Result<Vec<_>, String>>()?;
    Ok(LinkSpec { name: link.name.clone(), mass: link.inertial.mass.value, shapes })
}

fn joint_spec(j: &urdf_rs::Joint, parent: usize, child: usize) -> Result<JointSpec, String> {
    let kind = match j.joint_type {
        urdf_rs::JointType::Revolute => JointKind::Revolute,
        urdf_rs::JointType::Prismatic => JointKind::Prismatic,
        urdf_rs::JointType::Fixed => JointKind::Fixed,
        ref other => return Err(format!("joint `{}`: type {other:?} is not supported", j.name)),
    };
    let axis = Vector3::from(j.axis.xyz.0);
    if kind != JointKind::Fixed && axis.norm() < 1e-9 {
        return Err(format!("joint `{}`: zero axis", j.name));
    }
    let limit = &j.limit;
    if kind != JointKind::Fixed && !(limit.lower < limit.upper && limit.velocity > 0.0 && limit.effort > 0.0) {
        return Err(format!(
            "joint `{}`: limits need lower < upper and positive velocity and effort (got {}..{}, velocity {}, effort {})",
            j.name, limit.lower, limit.upper, limit.velocity, limit.effort
        ));
    }
    Ok(JointSpec {
        name: j.name.clone(),
        kind,
        parent,
        child,
        parent_from_joint: origin_pose(&j.origin),
        axis: Unit::try_new(axis, 1e-12).unwrap_or(Vector3::z_axis()),
        lower: limit.lower,
        upper: limit.upper,
        max_velocity: limit.velocity,
        max_effort: limit.effort,
    })
}

/// Joints sorted so each one's parent link is placed already; the root is the link that is
/// nobody's child.
fn root_to_leaf_order(joints: &[JointSpec], n_links: usize) -> Result<Vec<usize>, String> {
    let mut placed = vec![true; n_links];
    for j in joints {
        placed[j.child] = false;
    }
    if placed.iter().filter(|&&p| p).count() != 1 {
        return Err("the links must form one tree with a single root".into());
    }
    let mut order = Vec::new();
    while order.len() < joints.len() {
        let before = order.len();
        for (i, j) in joints.iter().enumerate() {
            if !order.contains(&i) && placed[j.parent] {
                placed[j.child] = true;
                order.push(i);
            }
        }
        if order.len() == before {
            return Err("the joints form a loop".into());
        }
    }
    Ok(order)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn umi() -> Arm {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../urdf/umi_rtx.urdf");
        Arm::from_urdf_file(&path).unwrap()
    }

    #[test]
    fn reads_the_umi_urdf() {
        let arm = umi();
        assert_eq!(arm.joint(0).kind, JointKind::Prismatic);
        assert!((arm.max_opening() - 0.1).abs() < 1e-12);
        assert!(arm.links.iter().any(|l| l.name == "base_link" && !l.shapes.is_empty()));
    }

    #[test]
    fn zero_pose_tool_hangs_straight_down_under_the_wrist() {
        let arm = umi();
        let q = [0.5, 0.0, 0.0, 0.0, 0.0, 0.0];
        let g = arm.base_from_gripper(&q);
        // Arm stretched along x: wrist centre at x = 0.504, tool 0.125 m straight down from it.
        let expect = Vector3::new(0.504, 0.0, 0.5 - 0.285);
        assert!((g.translation.vector - expect).norm() < 1e-12, "{}", g.translation.vector);
        let approach = g.rotation * Vector3::z();
        assert!((approach - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-12);
    }

    #[test]
    fn the_fingertips_reach_5_mm_past_the_tool_centre_point() {
        // The URDF puts the tcp 5 mm above the fingertips: finger boxes 60 mm long from 0.03 m
        // below the gripper link, the tcp 0.085 m below it.
        assert!((umi().fingertip_reach() - 0.005).abs() < 1e-12, "{}", umi().fingertip_reach());
    }

    #[test]
    fn a_joint_naming_a_missing_link_is_reported() {
        let text = r#"<robot name="r"><link name="a"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"#;
        let e = Arm::from_urdf_str(text, "x.urdf").unwrap_err().to_string();
        assert!(e.contains("x.urdf") && e.contains("no link `b`"), "{e}");
    }
}
