//! The arm in the rapier world: the URDF as a multibody on a fixed base, its joints driven by
//! position motors (with velocity feed-forward) that follow trajectories, and fingers as
//! motorised prismatic joints under the URDF's effort limit, so that only friction holds what
//! they close on.

use crate::convert;
use crate::physics::Cell;
use nalgebra::Isometry3;
use rapier3d::prelude::*;
use rapier3d_urdf::{UrdfLoaderOptions, UrdfMultibodyOptions, UrdfRobot};
use std::path::Path;

// The joint and link names and the URDF origin convention are the arm model's (`robot::arm`):
// the simulated arm and the planner's must be the same arm.
pub use robot::arm::{ARM_JOINTS, FINGER_JOINTS};
use robot::arm::{TCP_LINK, origin_pose};
/// Where the arm waits: folded, the gripper 0.215 m over the table, clear of the workspace.
pub const HOME: [f64; 6] = [0.5, 0.0, 2.0, 0.0, 0.0, 0.0];
/// The link the gripper (tool centre point) frame is fixed to, and the tcp's offset along its z.
const GRIPPER_LINK: &str = "gripper";

/// Position-motor gains of the arm joints (acceleration-based: independent of link masses).
/// 400 rad/s natural frequency, critically damped: gravity sags zed by g/k = 0.06 mm.
const ARM_STIFFNESS: f32 = 160_000.0;
const ARM_DAMPING: f32 = 800.0;
/// Finger motors: a stiff position servo whose force saturates at the URDF effort limit, so a
/// closing finger that meets the object presses on it with that force.
const FINGER_STIFFNESS: f32 = 40_000.0;
const FINGER_DAMPING: f32 = 400.0;
/// Friction of the finger pads and links (rubber pads on the fingers).
const PAD_FRICTION: f32 = 1.0;

#[derive(Debug, thiserror::Error)]
pub enum SimArmError {
    #[error("{file}: {message}")]
    Urdf { file: String, message: String },
}

/// Solver settings a cell needs for friction grasps, on top of [`Cell::new`]'s:
/// - 2 mm of speculative contact instead of rapier's default 20 mm, which let fingers passing a
///   few millimetres from an object push it without touching (an L-bracket 5.8 mm from a
///   finger was set rocking);
/// - two Gauss-Seidel passes per substep: with one, a wedge held by its end faces crept out of
///   the grip during transfers (4 of 6 seeded single-wedge picks dropped; with two, none did, for
///   a few per cent of simulation speed -- doubling substeps instead cost a third of it);
/// - no contact recycling: rapier keeps a pair's contact points while the pair has moved less
///   than 5 cm (its default), which let a flag held by its edge creep 8 mm and turn 7 deg in the
///   jaws while the arm swung it; recomputed every step, 2 mm and 2 deg.
pub fn configure_for_grasping(cell: &mut Cell) {
    let ip = &mut cell.world.integration_parameters;
    ip.normalized_prediction_distance = 0.002;
    ip.num_internal_pgs_iterations = 2;
    ip.contact_recycling = false;
}

/// Turns off continuous collision detection for a body the fingers will hold: with it, rapier
/// clamped the motion of a 4 mm flag squeezed between the pads until it slipped out (dropped
/// after 2 s of arm motion; without it, held). Objects dropped at these heights and speeds move
/// less than their thickness per step, so nothing tunnels.
pub fn hold_without_ccd(cell: &mut Cell, body: RigidBodyHandle) {
    cell.world.bodies[body].enable_ccd(false);
}

/// Albedo of the arm's links (anodised grey) and of its fingers.
const LINK_ALBEDO: f32 = 0.35;
const FINGER_ALBEDO: f32 = 0.6;

/// Handles of the arm's parts in the cell.
pub struct SimArm {
    joints: [MultibodyJointHandle; 6],
    fingers: [MultibodyJointHandle; 2],
    finger_force: [f32; 2],
    /// The arm joints' effort limits (N or N m), which cap their motors.
    effort: [f32; 6],
    gripper_body: RigidBodyHandle,
    gripper_from_tcp: Isometry3<f64>,
    /// The arm as built, when it is not its drawing: its encoders are read to their counts.
    as_built: Option<crate::realism::ArmAsBuilt>,
    /// Rigid bodies of the arm's links (for contact queries), and their URDF link names.
    pub bodies: Vec<RigidBodyHandle>,
    pub link_names: Vec<String>,
    pub finger_bodies: [RigidBodyHandle; 2],
    pub world_from_base: Isometry3<f64>,
}

impl SimArm {
    /// Loads the URDF at `path` into `cell` with its base at `world_from_base`, the arm joints at
    /// `q` and the fingers at `opening`; built off its drawing as `as_built` says, if given.
    pub fn insert(
        cell: &mut Cell,
        path: &Path,
        world_from_base: &Isometry3<f64>,
        q: &[f64; 6],
        opening: f64,
        as_built: Option<&crate::realism::ArmAsBuilt>,
    ) -> Result<SimArm, SimArmError> {
        let file = path.display().to_string();
        let err = |message: String| SimArmError::Urdf { file: file.clone(), message };
        let options = UrdfLoaderOptions {
            make_roots_fixed: true,
            shift: convert::pose(world_from_base),
            collider_blueprint: ColliderBuilder::default()
                .density(0.0)
                .friction(PAD_FRICTION)
                .friction_combine_rule(CoefficientCombineRule::Max),
            // A sleeping multibody ignores new motor targets; the arm is always under control.
            rigid_body_blueprint: RigidBodyBuilder::dynamic().can_sleep(false),
            ..Default::default()
        };
        let (robot, urdf) = match as_built {
            None => UrdfRobot::from_file(path, options, None).map_err(|e| err(e.to_string()))?,
            Some(built) => {
                let text = built.urdf_text(path).map_err(err)?;
                let dir = path.parent().unwrap_or(Path::new("."));
                UrdfRobot::from_str(&text, options, dir).map_err(|e| err(e.to_string()))?
            }
        };
        let joint_names: Vec<String> =
            robot.joints.iter().map(|j| urdf.joints[j.urdf_joint_index].name.clone()).collect();
        let link_names: Vec<String> = robot.links.iter().map(|l| urdf.links[l.urdf_link_index].name.clone()).collect();
        let tcp_joint = urdf.joints.iter().find(|j| j.child.link == TCP_LINK && j.parent.link == GRIPPER_LINK);
        let gripper_from_tcp = tcp_joint
            .map(|j| origin_pose(&j.origin))
            .ok_or_else(|| err(format!("needs a fixed joint from `{GRIPPER_LINK}` to `{TCP_LINK}`")))?;
        let w = &mut cell.world;
        let handles = robot.insert_using_multibody_joints(
            &mut w.bodies,
            &mut w.colliders,
            &mut w.multibody_joints,
            UrdfMultibodyOptions::DISABLE_SELF_CONTACTS,
        );
        let joint = |name: &str| {
            let i = joint_names.iter().position(|n| n == name).ok_or_else(|| err(format!("no joint `{name}`")))?;
            handles.joints[i].joint.ok_or_else(|| err(format!("joint `{name}` did not become a multibody joint")))
        };
        let body = |name: &str| {
            let i = link_names.iter().position(|n| n == name).ok_or_else(|| err(format!("no link `{name}`")))?;
            Ok::<_, SimArmError>(handles.links[i].body)
        };
        let mut joints = Vec::with_capacity(6);
        for name in ARM_JOINTS {
            joints.push(joint(name)?);
        }
        let joints: [MultibodyJointHandle; 6] = joints.try_into().expect("six arm joints");
        let fingers = [joint(FINGER_JOINTS[0])?, joint(FINGER_JOINTS[1])?];
        let effort = |name: &str| urdf.joints.iter().find(|j| j.name == name).map_or(0.0, |j| j.limit.effort as f32);
        let arm = SimArm {
            joints,
            fingers,
            finger_force: [effort(FINGER_JOINTS[0]), effort(FINGER_JOINTS[1])],
            effort: ARM_JOINTS.map(effort),
            gripper_body: body(GRIPPER_LINK)?,
            gripper_from_tcp,
            bodies: handles.links.iter().map(|l| l.body).collect(),
            link_names: link_names.clone(),
            finger_bodies: [body(FINGER_JOINTS[0])?, body(FINGER_JOINTS[1])?],
            world_from_base: *world_from_base,
            as_built: as_built.cloned(),
        };
        arm.couple_fingers(cell);
        arm.place(cell, q, opening);
        arm.command(cell, q, &[0.0; 6]);
        arm.grip(cell, opening);
        Ok(arm)
    }

    /// Gears the fingers together: without it two saturated force-limited fingers let the object
    /// slide between them along the jaw axis (no force restores the centring; measured: a widget
    /// slid 27 mm in the grip while moved).
    fn couple_fingers(&self, cell: &mut Cell) {
        let w = &mut cell.world.multibody_joints;
        let (_, left) = w.get(self.fingers[0]).expect("finger joint");
        let (mb, right) = w.get_mut(self.fingers[1]).expect("finger joint");
        mb.add_dof_coupling(MultibodyDofCoupling {
            link1: left,
            dof1: 0,
            axis1: 0,
            link2: right,
            dof2: 0,
            axis2: 0,
            coeff: 1.0,
            offset: 0.0,
        });
    }

    /// Puts the joints at `q` and the fingers at `opening` at once (before the simulation runs).
    fn place(&self, cell: &mut Cell, q: &[f64; 6], opening: f64) {
        let w = &mut cell.world;
        let half = [opening / 2.0; 2];
        let targets = self.joints.iter().zip(q).chain(self.fingers.iter().zip(half.iter()));
        for (&h, &value) in targets {
            let (mb, link) = w.multibody_joints.get_mut(h).expect("arm joint");
            let current = free_coordinate(&mb.link(link).unwrap().joint);
            mb.link_mut(link).unwrap().joint.apply_displacement(&[(value - current) as f32]);
        }
        let (mb, _) = w.multibody_joints.get_mut(self.joints[0]).expect("arm joint");
        mb.forward_kinematics(&w.bodies, true);
        mb.update_rigid_bodies(&mut w.bodies, true);
    }

    /// Sets the joint motors to track position `q` with velocity `qd`.
    pub fn command(&self, cell: &mut Cell, q: &[f64; 6], qd: &[f64; 6]) {
        for (k, &h) in self.joints.iter().enumerate() {
            let axis = if k == 0 { JointAxis::LinX } else { JointAxis::AngX };
            let (mb, link) = cell.world.multibody_joints.get_mut(h).expect("arm joint");
            let data = &mut mb.link_mut(link).unwrap().joint.data;
            data.set_motor(axis, q[k] as f32, qd[k] as f32, ARM_STIFFNESS, ARM_DAMPING);
            data.set_motor_max_force(axis, self.effort[k]);
        }
    }

    /// Drives both fingers towards `opening` (metres between the pads) under their force limit.
    pub fn grip(&self, cell: &mut Cell, opening: f64) {
        for (&h, &force) in self.fingers.iter().zip(&self.finger_force) {
            let (mb, link) = cell.world.multibody_joints.get_mut(h).expect("finger joint");
            let data = &mut mb.link_mut(link).unwrap().joint.data;
            data.set_motor(JointAxis::LinX, (opening / 2.0) as f32, 0.0, FINGER_STIFFNESS, FINGER_DAMPING);
            data.set_motor_model(JointAxis::LinX, MotorModel::ForceBased);
            data.set_motor_max_force(JointAxis::LinX, force);
        }
    }

    /// Measured arm joint values: the encoders' readings (to their counts, for an arm as built).
    pub fn joints(&self, cell: &Cell) -> [f64; 6] {
        std::array::from_fn(|k| {
            let q = self.coordinate(cell, self.joints[k]);
            self.as_built.as_ref().map_or(q, |b| b.read_encoder(k, q))
        })
    }

    /// Measured opening between the pads.
    pub fn opening(&self, cell: &Cell) -> f64 {
        self.fingers.iter().map(|&h| self.coordinate(cell, h)).sum()
    }

    fn coordinate(&self, cell: &Cell, h: MultibodyJointHandle) -> f64 {
        let (mb, link) = cell.world.multibody_joints.get(h).expect("arm joint");
        free_coordinate(&mb.link(link).unwrap().joint)
    }

    /// The gripper (tool centre point) frame in the world, as simulated.
    /// Each link's collision shapes as one mesh in the world, where the simulation has them
    /// now, with the link's name: how the cameras see the arm (the URDF has no visual shapes).
    /// Fingers are lighter than the rest.
    pub fn link_meshes(&self, cell: &Cell) -> Vec<(String, mesh::TriMesh)> {
        self.bodies
            .iter()
            .zip(&self.link_names)
            .map(|(&body, name)| {
                let albedo = if self.finger_bodies.contains(&body) { FINGER_ALBEDO } else { LINK_ALBEDO };
                let mut mesh = mesh::TriMesh::default();
                for &c in cell.world.bodies[body].colliders() {
                    if let Some(m) = crate::shape_mesh::collider_mesh(&cell.world.colliders[c], albedo) {
                        mesh.append(&m);
                    }
                }
                (name.clone(), mesh)
            })
            .filter(|(_, m)| !m.triangles.is_empty())
            .collect()
    }

    pub fn world_from_gripper(&self, cell: &Cell) -> Isometry3<f64> {
        convert::iso(cell.world.bodies[self.gripper_body].position()) * self.gripper_from_tcp
    }
}

/// The value of a one-degree-of-freedom joint.
fn free_coordinate(joint: &MultibodyJoint) -> f64 {
    let c = joint.coords();
    let locked = joint.data.locked_axes;
    if !locked.contains(JointAxesMask::LIN_X) { c[0] as f64 } else { c[3] as f64 }
}
