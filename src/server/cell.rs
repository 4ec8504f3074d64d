//! The simulated cell behind the robot server, on a thread of its own that owns the physics:
//! the "hardware" (the settled world in rapier, the arm, the cameras) and what the robot
//! server computes for it (the hand-eye transform, inverse kinematics, paths, pick execution).
//!
//! What it may know is what a real robot server knows: its arm model, its cell's fixed layout
//! (table, bins), its hand-eye file, and what requests carry. It never plans from the objects'
//! true poses: a pick is planned from the grasp (and object pose, and obstacles) the request
//! gives, and judged afterwards from the physics as `marvin pick` judges it. Only the `truth`
//! op, served only when the server was started for evaluation, reads the simulation's truth.

use super::{CellJob, Shared};
use crate::protocol::{
    BinBox, CaptureReply, ErrorCode, Frame, HelloReply, Intrinsics, MoveReply, MoveTarget, PROTOCOL, PickOutcomeKind,
    PickReply, PickSpec, Request, RigCalibration, StatusReply, ToolReply, TruthReply, WireError, WirePose,
};
use crate::server::pick::{Aim, HOME, PickCell, Workcell, grasp_candidates, place_target, static_obstacles};
use anyhow::Context;
use base64::Engine;
use mesh::{PinholeCamera, StereoCalibration};
use nalgebra::Isometry3;
use rapier3d::prelude::{ColliderHandle, RigidBodyHandle};
use robot::Joints;
use robot::pick::{FREE_SPEED, GraspCandidate, PickRequest, grasp_variants, plan_pick};
use robot::planner::{Attached, CollisionWorld, Obstacle, PlannerParams, Problem};
use robot::trajectory::{Limits, Trajectory};
use serde_json::Value;
use sim::physics::collision_shape;
use sim::render::{TOOL_ID, arm_link_id};
use sim::{Scenario, Scene};
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::sync::mpsc::Receiver;
use std::time::Instant;

/// What the cell is made from.
#[derive(Debug, Clone)]
pub struct CellConfig {
    pub world: PathBuf,
    /// Clutter and noise seed (default: the world file's).
    pub seed: Option<u64>,
    /// A hand-eye transform known from the start (`--hand-eye`).
    pub cam_from_base: Option<Isometry3<f64>>,
    /// Serve the `truth` op on the socket (`marvin serve --truth`: evaluation and tests from
    /// another process). [`super::Server::truth`] answers in-process whatever this says.
    pub expose_truth: bool,
    /// The cameras as measured (`--cameras`, from `marvin calibrate cameras`): what `capture`
    /// tells clients, as a camera driver publishes its calibration file. Without them the
    /// cameras are uncalibrated: `capture` carries no calibration.
    pub cameras: Option<StereoCalibration>,
}

/// Runs the cell: loads and settles the world, reports that it is ready (or why it cannot be),
/// then serves jobs until every sender is gone.
pub(crate) fn run(
    config: CellConfig,
    jobs: Receiver<CellJob>,
    shared: Arc<Shared>,
    ready: std::sync::mpsc::Sender<anyhow::Result<()>>,
) {
    let loaded = crate::server::pick::load(&config.world).and_then(|(scn, work)| {
        let world_bins = scn.world.bins.len();
        anyhow::ensure!(
            world_bins > 0,
            "{}: no [[bins]]: the robot server has nowhere to place",
            config.world.display()
        );
        Ok((scn, work))
    });
    let (scn, work) = match loaded {
        Ok(x) => x,
        Err(e) => {
            let _ = ready.send(Err(e));
            return;
        }
    };
    let seed = config.seed.unwrap_or(scn.world.seed);
    let scene = Scene::settle(&scn, seed);
    if let Some(why) = scene.unsettled() {
        tracing::warn!("an unsettled scene, {why}");
    }
    let mut cell = match SimCell::new(&scn, &work, &scene, &config, seed) {
        Ok(c) => c,
        Err(e) => {
            let _ = ready.send(Err(e));
            return;
        }
    };
    let _ = ready.send(Ok(()));
    cell.publish(&shared, false);
    for job in jobs {
        let outcome =
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| cell.serve(&job.request, job.in_process)));
        let result = outcome.unwrap_or_else(|panic| {
            let why =
                panic.downcast_ref::<String>().cloned().or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()));
            tracing::error!(op = job.request.op(), "the cell panicked: {why:?}");
            Err(WireError::new(ErrorCode::Internal, format!("the cell failed: {}", why.unwrap_or_default())))
        });
        cell.publish(&shared, false);
        if job.request.is_motion() {
            shared.moving.store(false, Ordering::SeqCst);
        }
        let _ = job.reply.send(result);
    }
}

/// The cell and the robot server's state.
struct SimCell<'a> {
    scn: &'a Scenario,
    work: &'a Workcell,
    pick: PickCell<'a>,
    /// How the cell's cameras form images (the world's realism preset); its `rig` is the
    /// truth, which no client is told.
    imaging: sim::imaging::Imaging,
    /// The cameras as measured, if the server was given them (`--cameras`).
    cameras: Option<StereoCalibration>,
    cam_from_base: Option<Isometry3<f64>>,
    expose_truth: bool,
    seed: u64,
    /// Captures and motions so far: each gets a seed of its own (sensor noise, planner).
    captures: u64,
    motions: u64,
    /// The tool the operator handed into the gripper, if any.
    tool: Option<HeldTool>,
    /// Why the scene had not settled when the cell started, if it had not (for `truth`).
    unsettled: Option<String>,
}

/// A tool in the gripper: its name, body, and where the robot believes it sits in the gripper
/// (the tool's URDF), for planning around it.
struct HeldTool {
    name: String,
    body: RigidBodyHandle,
    gripper_from_tool: Isometry3<f64>,
    shape: parry3d::shape::SharedShape,
    /// The colliders of its jaw inserts on the fingers.
    inserts: Vec<ColliderHandle>,
}

/// Gauss-Seidel passes per substep while a tool is held (`sim::arm::configure_for_grasping`
/// sets 2 for picks, restored when the tool is stowed).
const TOOL_PGS_ITERATIONS: usize = 8;

/// The natural frequency of contacts (Hz) while a tool is held, instead of the world's
/// (`sim::physics::CONTACT_FREQUENCY_HZ`). The flag is held by its locators in its jaw inserts'
/// holes (`urdf/flag_tool.urdf`), so what is left of its creep is the give of its contacts and
/// the holes' clearance: it rocks on the pads and leans on the holes' walls. Over 10
/// calibrations (`marvin eval calibrate worlds/widgets.toml --trials 10`, seeds 1-10), with the
/// locators in recesses of the pads themselves (a first design): at the world's 200 Hz the flag
/// moved 0.095 mm (median; 0.16 at most) between the first and last sighting, at 2000 Hz 0.024 mm
/// (0.060); halving the time step as well was no better. With the inserts at 4000 Hz, one of the
/// ten handovers lost the flag. Held by friction alone it had crept 0.8-1.4 mm: rapier solves
/// friction on velocities, so nothing brings a slipped body back.
const TOOL_CONTACT_FREQUENCY_HZ: f32 = 2000.0;

/// Handovers tried before `take_tool` gives up, and how near the seated opening the jaws must
/// close for the tool to count as seated (metres; seated, they closed within 0.003 mm of it; on
/// a rim, 0.8 mm or more wide; dropped, 4 mm narrow). Over 30 calibrations one handover in 30
/// left the flag unseated, and it fell: that is the first handover in a cell. Once a tool has
/// been taken and stowed (the board before the flag, as `marvin run` does), the seat is a coin
/// toss: 9 of 17 and 15 of 31 handovers seated the flag at the home pose (before and after a
/// camera calibration); the outcome depends chaotically on the physics' history, and what
/// carries it over was not found. Eight tries leave about 1 in 250 handovers failed.
const HANDOVER_TRIES: usize = 8;
const SEATED_TOLERANCE_M: f64 = 1e-4;

/// Seconds the tool is left to settle onto its locators' walls under its weight once the
/// operator lets go, before the arm moves.
const TOOL_SEAT_S: f64 = 0.15;

/// The tools an operator can hand in, each a library model with its URDF next to the arm's: the
/// camera calibration board (`urdf/board_tool.urdf`) and the hand-eye flag (`urdf/flag_tool.urdf`).
const TOOLS: [(&str, &str); 2] = [("board", "board_tool.urdf"), ("flag", "flag_tool.urdf")];

impl<'a> SimCell<'a> {
    fn new(
        scn: &'a Scenario,
        work: &'a Workcell,
        scene: &Scene,
        config: &CellConfig,
        seed: u64,
    ) -> anyhow::Result<SimCell<'a>> {
        let pick = PickCell::new(scn, work, scene).context("putting the arm into the cell")?;
        Ok(SimCell {
            scn,
            work,
            pick,
            imaging: sim::imaging::Imaging::new(&scn.world),
            cam_from_base: config.cam_from_base,
            expose_truth: config.expose_truth,
            cameras: config.cameras.clone(),
            seed,
            captures: 0,
            motions: 0,
            tool: None,
            unsettled: scene.unsettled(),
        })
    }

    fn serve(&mut self, request: &Request, in_process: bool) -> Result<Value, WireError> {
        match request {
            Request::Hello { .. } => json(Ok(self.hello())),
            Request::Capture {} => json(self.capture()),
            Request::Move(target) => json(self.move_to(target)),
            Request::Home {} => json(self.move_to_joints(&HOME, FREE_SPEED)),
            Request::SetHandEye { cam_from_base } => {
                self.cam_from_base = Some(cam_from_base.to_isometry("cam_from_base")?);
                Ok(serde_json::json!({ "calibrated": true }))
            }
            Request::Pick(spec) => json(self.pick(spec)),
            Request::TakeTool { tool } => json(self.take_tool(tool)),
            Request::StowTool {} => json(self.stow_tool()),
            Request::Truth {} if self.expose_truth || in_process => json(Ok(self.truth())),
            Request::Truth {} => Err(WireError::new(
                ErrorCode::BadRequest,
                "`truth` is served only by a server started with --truth (evaluation)",
            )),
            Request::Status {} | Request::Shutdown {} | Request::Bye {} => {
                Err(WireError::new(ErrorCode::Internal, format!("`{}` is not the cell's to serve", request.op())))
            }
        }
    }

    /// Updates the status every connection reads without waiting for the cell.
    fn publish(&self, shared: &Shared, moving: bool) {
        let status = StatusReply {
            joints: self.joint_map(&self.joints()),
            gripper_opening_mm: self.pick.arm.opening(&self.pick.cell) * 1e3,
            holding: self.tool.as_ref().map(|t| t.name.clone()),
            calibrated: self.cam_from_base.is_some(),
            sim_time_s: self.pick.simulated_s,
            moving,
        };
        *shared.status.lock().unwrap_or_else(|e| e.into_inner()) = status;
    }

    fn hello(&self) -> HelloReply {
        HelloReply {
            server: format!("marvin robot server {}", env!("CARGO_PKG_VERSION")),
            protocol: PROTOCOL,
            models: self.scn.library.names().map(str::to_string).collect(),
            bins: self.scn.world.bins.iter().map(|b| b.name.clone()).collect(),
            bin_boxes: self.scn.world.bins.iter().map(|b| self.bin_box(b)).collect(),
            // The world's origin is the centre of the table's top.
            table_top_base_m: Some((self.work.world_from_base.inverse() * nalgebra::Point3::origin()).z),
            calibrated: self.cam_from_base.is_some(),
        }
    }

    /// A bin's inside (floor to rim) as a box aligned with the base frame.
    fn bin_box(&self, bin: &sim::world::BinSpec) -> BinBox {
        let base_from_world = self.work.world_from_base.inverse();
        let [sx, sy, depth] = bin.size_m;
        let corners: Vec<nalgebra::Point3<f64>> = [-0.5, 0.5]
            .iter()
            .flat_map(|&u| [-0.5, 0.5].into_iter().flat_map(move |v| [0.0, 1.0].map(|w| (u, v, w))))
            .map(|(u, v, w)| {
                let world =
                    nalgebra::Point3::new(bin.centre_m[0] + u * sx, bin.centre_m[1] + v * sy, bin.wall_m + w * depth);
                base_from_world * world
            })
            .collect();
        let lo = corners.iter().fold(corners[0], |m, p| m.inf(p));
        let hi = corners.iter().fold(corners[0], |m, p| m.sup(p));
        let c = nalgebra::center(&lo, &hi);
        BinBox {
            name: bin.name.clone(),
            centre_base_m: [c.x, c.y, c.z],
            size_m: [hi.x - lo.x, hi.y - lo.y, hi.z - lo.z],
        }
    }

    fn joints(&self) -> Joints {
        self.pick.arm.joints(&self.pick.cell)
    }

    fn joint_map(&self, q: &Joints) -> BTreeMap<String, f64> {
        (0..6).map(|k| (self.work.arm.joint(k).name.clone(), q[k])).collect()
    }

    /// The stereo pair as the cameras see the cell now.
    fn capture(&mut self) -> Result<CaptureReply, WireError> {
        let im = &self.imaging;
        let statics =
            sim::scene::static_boxes(&self.scn.world).into_iter().map(|b| (0, b.mesh(), im.static_finish(&b)));
        let objects: Vec<_> = self
            .pick
            .objects
            .iter()
            .map(|(id, model, body)| {
                let m = &self.scn.library.models[model];
                (*id, m.mesh.transformed(&self.pick.cell.pose(*body)), im.object_finish(m, *id, self.seed))
            })
            .collect();
        let arm = self
            .pick
            .arm
            .link_meshes(&self.pick.cell)
            .into_iter()
            .enumerate()
            .map(|(k, (_, m))| (arm_link_id(k), m, sim::imaging::ARM_FINISH));
        let tool = self.tool.as_ref().map(|t| {
            let model = &self.scn.library.models[&t.name];
            (TOOL_ID, model.mesh.transformed(&self.pick.cell.pose(t.body)), im.object_finish(model, TOOL_ID, 0))
        });
        let rs = im.scene(statics.chain(objects).chain(arm).chain(tool));
        self.captures += 1;
        let noise_seed = self.seed.wrapping_mul(1_000_003).wrapping_add(self.captures);
        let (left, right) = im.render_stereo(&rs, noise_seed);
        Ok(CaptureReply {
            left_png_b64: png_b64(&left.image, left.width, left.height)?,
            right_png_b64: png_b64(&right.image, right.width, right.height)?,
            calibration: self.cameras.as_ref().map(rig_calibration),
            sim_time_s: self.pick.simulated_s,
        })
    }

    /// `base_from_x` for a pose given in `base` or `cam`.
    fn in_base(&self, frame: Frame, pose: Isometry3<f64>) -> Result<Isometry3<f64>, WireError> {
        match frame {
            Frame::Base => Ok(pose),
            Frame::Cam => {
                let cam_from_base = self.cam_from_base.ok_or_else(|| {
                    WireError::new(
                        ErrorCode::NotCalibrated,
                        "a `cam`-frame pose needs the hand-eye transform: send set_hand_eye first",
                    )
                })?;
                Ok(cam_from_base.inverse() * pose)
            }
            Frame::Gripper => Err(WireError::new(ErrorCode::BadRequest, "poses here are in `base` or `cam`")),
        }
    }

    fn move_to(&mut self, target: &MoveTarget) -> Result<MoveReply, WireError> {
        let speed = target.speed.unwrap_or(FREE_SPEED);
        if !(speed.is_finite() && speed > 0.0 && speed <= 1.0) {
            return Err(WireError::new(ErrorCode::BadRequest, format!("`speed` must be in (0, 1], got {speed}")));
        }
        let goal = match (&target.tool, &target.joints) {
            (Some(tool), None) => {
                let (frame, pose) = tool.in_frames("tool", &[Frame::Base, Frame::Cam])?;
                let base_from_gripper = self.in_base(frame, pose)?;
                self.work
                    .ik
                    .solve_near(&base_from_gripper, &self.joints())
                    .map_err(|e| WireError::new(ErrorCode::Unreachable, format!("the tool pose: {e}")))?
            }
            (None, Some(named)) => self.joints_named(named)?,
            _ => return Err(WireError::new(ErrorCode::BadRequest, "`move` takes exactly one of `tool` and `joints`")),
        };
        self.move_to_joints(&goal, speed)
    }

    /// The current joints with those named replaced, each checked against its limits.
    fn joints_named(&self, named: &BTreeMap<String, f64>) -> Result<Joints, WireError> {
        let mut q = self.joints();
        for (name, value) in named {
            let k = (0..6).find(|&k| self.work.arm.joint(k).name == *name).ok_or_else(|| {
                let known: Vec<&str> = (0..6).map(|k| self.work.arm.joint(k).name.as_str()).collect();
                WireError::new(
                    ErrorCode::BadRequest,
                    format!("no joint `{name}`; the arm's joints: {}", known.join(", ")),
                )
            })?;
            if !value.is_finite() {
                return Err(WireError::new(ErrorCode::BadRequest, format!("joint `{name}`: {value} is not finite")));
            }
            let j = self.work.arm.joint(k);
            if *value < j.lower || *value > j.upper {
                return Err(WireError::new(
                    ErrorCode::Unreachable,
                    format!("joint `{name}` at {value:.4} is outside its limits {:.4}..{:.4}", j.lower, j.upper),
                ));
            }
            q[k] = *value;
        }
        Ok(q)
    }

    /// Plans a collision-free path among the cell's fixed boxes to `goal` and follows it.
    fn move_to_joints(&mut self, goal: &Joints, speed: f64) -> Result<MoveReply, WireError> {
        let start = self.joints();
        let opening = self.pick.arm.opening(&self.pick.cell);
        let world =
            CollisionWorld::new(&self.work.arm, static_obstacles(self.scn, self.work), robot::pick::FREE_CLEARANCE_M);
        self.motions += 1;
        let held =
            self.tool.as_ref().map(|t| Attached { shape: t.shape.clone(), gripper_from_shape: t.gripper_from_tool });
        let path = Problem { arm: &self.work.arm, world: &world, opening, attached: held.as_ref() }
            .plan(&start, goal, &PlannerParams::default(), self.motion_seed())
            .map_err(|e| WireError::new(ErrorCode::NoPath, e.to_string()))?;
        let limits = Limits { velocity: self.work.arm.max_velocity(), acceleration: self.work.arm.max_acceleration() };
        let t0 = self.pick.simulated_s;
        let err = self.pick.follow(&Trajectory::piecewise(&path, &limits.scaled(speed)));
        let q = self.joints();
        Ok(MoveReply {
            base_from_gripper: WirePose::new(Some(Frame::Base), &self.work.arm.base_from_gripper(&q)),
            joints: self.joint_map(&q),
            motion_s: self.pick.simulated_s - t0,
            max_tracking_error: err,
        })
    }

    fn motion_seed(&self) -> u64 {
        self.seed.wrapping_mul(6364136223846793005).wrapping_add(self.motions)
    }

    fn pick(&mut self, spec: &PickSpec) -> Result<PickReply, WireError> {
        if let Some(t) = &self.tool {
            return Err(WireError::new(
                ErrorCode::BadRequest,
                format!("the gripper holds the {}: stow_tool first", t.name),
            ));
        }
        let t0 = Instant::now();
        let request = self.pick_request(spec)?;
        let bin = self.scn.world.bins.iter().position(|b| b.name == spec.place.bin).expect("checked in pick_request");
        let plan = plan_pick(&self.work.arm, &self.work.ik, &request).map_err(|e| self.why_unplanned(&request, e))?;
        let plan_ms = t0.elapsed().as_secs_f64() * 1e3;
        let tcp_path_base_m = self.tcp_path(&plan);
        let grip_past_com_mm = Some(plan.grip_past_com_m * 1e3);
        if spec.plan_only {
            let grasp_index = plan.grasp_index;
            return Ok(PickReply {
                outcome: None,
                detail: None,
                plan_ms,
                motion_s: 0.0,
                grasp_index,
                closed_opening_mm: None,
                grip_past_com_mm,
                tcp_path_base_m,
            });
        }
        self.pick.bin = bin;
        let aim = Aim::Pose(self.work.world_from_base * request.target.base_from_shape);
        let out = self.pick.run_plan_on(aim, Ok(plan));
        let outcome = match out.result.as_str() {
            "placed" => PickOutcomeKind::Placed,
            "miss" => PickOutcomeKind::Miss,
            "slip" => PickOutcomeKind::Slip,
            "drop" => PickOutcomeKind::Drop,
            "wrong part" => PickOutcomeKind::WrongPart,
            _ => PickOutcomeKind::OutsideBin,
        };
        Ok(PickReply {
            outcome: Some(outcome),
            detail: out.detail,
            plan_ms,
            motion_s: out.simulated_s,
            grasp_index: out.grasp.unwrap_or(0),
            closed_opening_mm: out.closed_opening_mm,
            grip_past_com_mm,
            tcp_path_base_m,
        })
    }

    /// The tool centre point along a plan's moves (their waypoints, by forward kinematics).
    fn tcp_path(&self, plan: &robot::pick::PickPlan) -> Vec<[f64; 3]> {
        plan.steps
            .iter()
            .filter_map(|step| match &step.action {
                robot::pick::Action::Move(traj) => Some(traj),
                robot::pick::Action::Grip { .. } => None,
            })
            .flat_map(|traj| traj.points())
            .map(|q| {
                let p = self.work.arm.base_from_gripper(q).translation.vector;
                [p.x, p.y, p.z]
            })
            .collect()
    }

    /// A planning failure as the protocol reports it: `unreachable` when inverse kinematics
    /// has no solution at any grasp offered, `no_path` when solutions exist but every plan
    /// through them collides.
    fn why_unplanned(&self, request: &PickRequest, e: robot::pick::PickError) -> WireError {
        let ik_errors: Vec<String> = request
            .grasps
            .iter()
            .filter_map(|g| self.work.ik.solve_near(&g.base_from_gripper, &request.start).err())
            .map(|e| e.to_string())
            .collect();
        if ik_errors.len() == request.grasps.len() {
            let first = ik_errors.first().cloned().unwrap_or_default();
            WireError::new(ErrorCode::Unreachable, format!("no grasp offered can be reached ({first}); {e}"))
        } else {
            WireError::new(ErrorCode::NoPath, e.to_string())
        }
    }

    /// The planner's problem from what the request says, every field checked.
    fn pick_request(&mut self, spec: &PickSpec) -> Result<PickRequest, WireError> {
        let model = self.scn.library.models.get(&spec.model).ok_or_else(|| {
            WireError::new(
                ErrorCode::UnknownModel,
                format!("no model `{}`; the library: {}", spec.model, self.model_names()),
            )
        })?;
        if !self.scn.world.bins.iter().any(|b| b.name == spec.place.bin) {
            let bins: Vec<&str> = self.scn.world.bins.iter().map(|b| b.name.as_str()).collect();
            return Err(WireError::new(
                ErrorCode::UnknownBin,
                format!("no bin `{}`; the cell's: {}", spec.place.bin, bins.join(", ")),
            ));
        }
        let jaw = spec.grasp.jaw_mm * 1e-3;
        let max = self.work.arm.max_opening();
        if !(jaw.is_finite() && jaw > 0.0 && jaw <= max) {
            return Err(WireError::new(
                ErrorCode::BadRequest,
                format!("`grasp.jaw_mm` must be in (0, {:.0}], got {}", max * 1e3, spec.grasp.jaw_mm),
            ));
        }
        let (frame, pose) = spec.grasp.pose().in_frames("grasp", &[Frame::Base, Frame::Cam])?;
        let base_from_gripper = self.in_base(frame, pose)?;
        let base_from_model = match &spec.object {
            Some(o) => {
                let (frame, pose) = o.in_frames("object", &[Frame::Base, Frame::Cam])?;
                self.in_base(frame, pose)?
            }
            // The model's grasp of the nearest jaw opening says where the object must be.
            None => {
                let g = model
                    .grasps
                    .iter()
                    .min_by(|a, b| (a.opening - jaw).abs().total_cmp(&(b.opening - jaw).abs()))
                    .ok_or_else(|| {
                        WireError::new(ErrorCode::BadRequest, format!("model `{}` has no grasps", model.name))
                    })?;
                base_from_gripper * g.model_from_gripper.inverse()
            }
        };
        let mut obstacles = static_obstacles(self.scn, self.work);
        for (k, o) in spec.obstacles.iter().enumerate() {
            let other = self.scn.library.models.get(&o.model).ok_or_else(|| {
                WireError::new(ErrorCode::UnknownModel, format!("`obstacles[{k}].model`: no model `{}`", o.model))
            })?;
            let (frame, pose) = o.pose.in_frames(&format!("obstacles[{k}].pose"), &[Frame::Base, Frame::Cam])?;
            obstacles.push(Obstacle {
                name: format!("{} (obstacle {k})", o.model),
                shape: collision_shape(other),
                base_from_shape: self.in_base(frame, pose)?,
            });
        }
        // The grasp asked for first (and its equivalent holds), then the model's others.
        let mut grasps: Vec<GraspCandidate> = grasp_variants(&base_from_gripper)
            .into_iter()
            .map(|g| GraspCandidate { base_from_gripper: g, width: jaw })
            .collect();
        if spec.object.is_some() {
            grasps.extend(grasp_candidates(model, &base_from_model));
        }
        let bin = self.scn.world.bins.iter().find(|b| b.name == spec.place.bin).expect("checked above");
        self.motions += 1;
        Ok(PickRequest {
            grasps,
            target: Obstacle {
                name: format!("the {} picked", model.name),
                shape: collision_shape(model),
                base_from_shape: base_from_model,
            },
            target_com: base_from_model * model.mass.centre_of_mass,
            obstacles,
            place: place_target(self.work, bin, self.pick.released),
            start: self.joints(),
            seed: self.motion_seed(),
        })
    }

    /// The operator puts the tool between the open jaws where its URDF says it is held; the
    /// jaws close on it under their force limit (friction alone holds it).
    fn take_tool(&mut self, name: &str) -> Result<ToolReply, WireError> {
        if let Some(t) = &self.tool {
            return Err(WireError::new(
                ErrorCode::BadRequest,
                format!("the gripper already holds the {}: stow_tool first", t.name),
            ));
        }
        let file = TOOLS.iter().find(|(n, _)| *n == name).map(|(_, f)| *f).ok_or_else(|| {
            let names: Vec<&str> = TOOLS.iter().map(|(n, _)| *n).collect();
            WireError::new(ErrorCode::UnknownModel, format!("no tool `{name}`; the cell's tools: {}", names.join(", ")))
        })?;
        let internal = |m: String| WireError::new(ErrorCode::Internal, m);
        let tool = robot::tool::Tool::from_urdf_file(&self.work.urdf.with_file_name(file))
            .map_err(|e| internal(e.to_string()))?;
        let model =
            self.scn.library.models.get(name).ok_or_else(|| internal(format!("the library has no model `{name}`")))?;
        // More Gauss-Seidel passes while the tool is held stop it turning in the jaws (12 moves,
        // held by friction: 0.77 -> 0.06 deg); stiffer contacts keep its locators where they sit.
        let ip = &mut self.pick.cell.world.integration_parameters;
        ip.num_internal_pgs_iterations = TOOL_PGS_ITERATIONS;
        ip.contact_softness.natural_frequency = TOOL_CONTACT_FREQUENCY_HZ;
        let seated = 2.0 * tool.insert_reach();
        let mut jaws = Vec::new();
        for _ in 0..HANDOVER_TRIES {
            let (body, inserts) = self.hand_in(&tool, model);
            let jaw = self.pick.arm.opening(&self.pick.cell);
            jaws.push(format!("{:.2}", jaw * 1e3));
            if tool.inserts.iter().all(|i| i.is_empty()) || (jaw - seated).abs() <= SEATED_TOLERANCE_M {
                let gripper_from_tool = tool.tool_from_gripper.inverse();
                let shape = collision_shape(model);
                self.tool = Some(HeldTool { name: name.to_string(), body, gripper_from_tool, shape, inserts });
                return Ok(ToolReply { holding: Some(name.to_string()), jaw_mm: jaw * 1e3 });
            }
            // Not seated (a locator on a hole's rim, or the tool dropped): take it back, try again.
            self.open_to_take(&tool, model);
            self.pick.cell.remove(body);
            self.pick.cell.detach(&inserts);
        }
        self.restore_physics_after_tool();
        Err(internal(format!(
            "the {name} did not seat in its jaw inserts in {HANDOVER_TRIES} handovers (seated, the jaws close to {:.2} mm \
             on it; they closed to {} mm)",
            seated * 1e3,
            jaws.join(", ")
        )))
    }

    /// Opens the jaws wide enough to take the tool (or to let it go).
    fn open_to_take(&mut self, tool: &robot::tool::Tool, model: &mesh::Model) {
        let width = model.grasps.first().map_or(0.0, |g| g.opening);
        self.pick.grip(tool.opening_to_take(width) + robot::pick::OPEN_MARGIN_M);
    }

    /// One handover: the jaws open, the inserts are clipped on, the operator holds the tool
    /// between them while they close, and lets go.
    fn hand_in(&mut self, tool: &robot::tool::Tool, model: &mesh::Model) -> (RigidBodyHandle, Vec<ColliderHandle>) {
        self.open_to_take(tool, model);
        let world_from_gripper = self.pick.arm.world_from_gripper(&self.pick.cell);
        let at = world_from_gripper * tool.tool_from_gripper.inverse();
        let inserts = self.fit_inserts(tool, &world_from_gripper);
        let body = self.pick.cell.add_tool(model, &at);
        let locators: Vec<_> = tool.locators.iter().map(|b| (at * b.tool_from_box, b.half_extents)).collect();
        self.pick.cell.attach_boxes(body, &locators);
        sim::arm::hold_without_ccd(&mut self.pick.cell, body);
        // The operator holds the tool still while the jaws close on it, so that its locators
        // meet the inserts' holes where they are.
        self.pick.cell.hold_in_place(body, true);
        self.pick.grip(0.0);
        self.pick.cell.hold_in_place(body, false);
        self.pick.run_for(TOOL_SEAT_S);
        (body, inserts)
    }

    /// Clips the tool's jaw inserts onto the open fingers' pads: each where it will be once the
    /// jaws close on the tool, less the distance its finger has still to travel.
    fn fit_inserts(&mut self, tool: &robot::tool::Tool, world_from_gripper: &Isometry3<f64>) -> Vec<ColliderHandle> {
        let travel = self.pick.arm.opening(&self.pick.cell) / 2.0 - tool.insert_reach();
        let mut colliders = Vec::new();
        for (k, (boxes, sign)) in tool.inserts.iter().zip([1.0, -1.0]).enumerate() {
            let shifted = Isometry3::translation(0.0, sign * travel, 0.0);
            let at: Vec<_> =
                boxes.iter().map(|b| (world_from_gripper * shifted * b.tool_from_box, b.half_extents)).collect();
            colliders.extend(self.pick.cell.attach_boxes(self.pick.arm.finger_bodies[k], &at));
        }
        colliders
    }

    /// The solver's settings for picks again (see `take_tool`).
    fn restore_physics_after_tool(&mut self) {
        sim::arm::configure_for_grasping(&mut self.pick.cell);
        self.pick.cell.world.integration_parameters.contact_softness.natural_frequency =
            sim::physics::CONTACT_FREQUENCY_HZ;
    }

    /// The jaws open and the operator takes the tool away.
    fn stow_tool(&mut self) -> Result<ToolReply, WireError> {
        let tool =
            self.tool.take().ok_or_else(|| WireError::new(ErrorCode::BadRequest, "the gripper holds no tool"))?;
        let width = self.scn.library.models.get(&tool.name).and_then(|m| m.grasps.first()).map_or(0.0, |g| g.opening);
        self.pick.grip(width + robot::pick::OPEN_MARGIN_M);
        self.pick.cell.remove(tool.body);
        self.pick.cell.detach(&tool.inserts);
        self.restore_physics_after_tool();
        Ok(ToolReply { holding: None, jaw_mm: self.pick.arm.opening(&self.pick.cell) * 1e3 })
    }

    fn model_names(&self) -> String {
        self.scn.library.names().collect::<Vec<_>>().join(", ")
    }

    /// The simulation's truth, for evaluation only.
    fn truth(&self) -> TruthReply {
        let objects = self.pick.truth_objects();
        // The true (as-built) left camera: what the hand-eye calibration should find.
        let world_from_cam = self.imaging.rig.left.pinhole.world_from_cam;
        let world_from_gripper = self.pick.arm.world_from_gripper(&self.pick.cell);
        TruthReply {
            objects,
            tool_in_gripper: self
                .tool
                .as_ref()
                .map(|t| WirePose::new(None, &(world_from_gripper.inverse() * self.pick.cell.pose(t.body)))),
            world_from_base: WirePose::new(None, &self.work.world_from_base),
            world_from_cam: WirePose::new(None, &world_from_cam),
            cam_from_base: WirePose::new(None, &(world_from_cam.inverse() * self.work.world_from_base)),
            unsettled: self.unsettled.clone(),
        }
    }
}

/// What the stereo head knows of itself: intrinsics, and the right camera in the left's frame.
pub fn rig_calibration(calib: &StereoCalibration) -> RigCalibration {
    let intrinsics = |c: &PinholeCamera| Intrinsics {
        width: c.width,
        height: c.height,
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
        distortion: c.distortion.d(),
    };
    let left_from_right = calib.left.world_from_cam.inverse() * calib.right.world_from_cam;
    RigCalibration {
        left: intrinsics(&calib.left),
        right: intrinsics(&calib.right),
        left_from_right: WirePose::new(None, &left_from_right),
    }
}

/// A reply as the JSON fields it adds to `{"id":..,"ok":true}`.
fn json<T: serde::Serialize>(reply: Result<T, WireError>) -> Result<Value, WireError> {
    reply.map(|r| serde_json::to_value(r).expect("replies serialise"))
}

fn png_b64(pixels: &[u8], width: usize, height: usize) -> Result<String, WireError> {
    use image::ImageEncoder;
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(pixels, width as u32, height as u32, image::ExtendedColorType::L8)
        .map_err(|e| WireError::new(ErrorCode::Internal, format!("encoding the image: {e}")))?;
    Ok(base64::engine::general_purpose::STANDARD.encode(png))
}
