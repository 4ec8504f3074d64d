//! Physical pick and place in the simulated cell: the arm is loaded into a rapier world holding a
//! settled scene, a pick plan is made for an object from its pose (ground truth here; the
//! end-to-end work will hand in vision's pose), the motors follow the plan, and the outcome is
//! judged from the physics alone: held = between the fingers and lifted with them; placed = as
//! [`super::judge`] rules (at rest inside the bin's walls, not piled over its rim, touching no
//! finger, and the part the pick aimed at).

use super::judge::{Part, aimed_at, why_not_placed};
use anyhow::{Result, anyhow};
use mesh::Model;
use nalgebra::{Isometry3, Point3, Vector3};
use rapier3d::prelude::RigidBodyHandle;
use robot::pick::{Action, GraspCandidate, PickPlan, PickRequest, PlaceTarget, grasp_variants, plan_pick};
use robot::planner::Obstacle;
use robot::{Arm, Ik};
use serde::{Deserialize, Serialize};
use sim::arm::SimArm;
use sim::physics::{Cell, collision_shape};
use sim::scene::{Scenario, Scene, static_boxes};
use std::path::PathBuf;

pub use sim::arm::HOME;
/// How long the cell runs after a move or a grip command before the next one, seconds.
const HOLD_S: f64 = 0.15;
/// Longest a grip command may take to come to rest, seconds.
const GRIP_LIMIT_S: f64 = 1.5;
/// Time allowed for a released object to come to rest, seconds.
const REST_LIMIT_S: f64 = 3.0;
/// A lifted object must have risen at least this fraction of the lift.
const LIFTED_FRACTION: f64 = 0.5;
/// A held object's centre stays within this distance of the tool centre point, metres.
const HELD_RADIUS_M: f64 = 0.08;

/// The robot side of a scenario: the arm model, its IK and where it stands.
pub struct Workcell {
    pub urdf: PathBuf,
    pub arm: Arm,
    pub ik: Ik,
    pub world_from_base: Isometry3<f64>,
}

impl Workcell {
    pub fn new(scn: &Scenario) -> Result<Workcell> {
        let no_robot = || anyhow!("{}: no [robot] section: this world has no arm to pick with", scn.path.display());
        let spec = scn.world.robot.as_ref().ok_or_else(no_robot)?;
        let urdf = scn.robot_urdf.clone().ok_or_else(no_robot)?;
        let arm = Arm::from_urdf_file(&urdf)?;
        let ik = Ik::new(&arm, &urdf.display().to_string())?;
        Ok(Workcell { urdf, arm, ik, world_from_base: spec.world_from_base() })
    }
}

/// How one pick went.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PickOutcome {
    pub object: u32,
    pub model: String,
    /// `placed`, or what went wrong: `unplanned`, `miss`, `slip`, `drop`, `outside bin`,
    /// `wrong part` (another body than the one aimed at was lifted).
    pub result: String,
    pub placed: bool,
    pub held: bool,
    pub detail: Option<String>,
    pub grasp: Option<usize>,
    pub simulated_s: f64,
    /// Worst arm joint tracking error during moves (zed in metres, others radians).
    pub max_tracking_error: f64,
    /// The move where that happened.
    pub worst_tracking_step: Option<String>,
    /// Opening of the closed fingers on the object, mm (the object's width if all went well).
    pub closed_opening_mm: Option<f64>,
    /// The width across the jaws of the grasp planned, mm: what `closed_opening_mm` should be.
    pub grasp_width_mm: Option<f64>,
    /// How far the planned fingertips reach past the object's centre of mass along the
    /// approach, mm (negative: short of it).
    #[serde(default)]
    pub grip_past_com_mm: Option<f64>,
    /// The object lifted, when it was not the one aimed at (a `wrong part`).
    pub lifted_instead: Option<u32>,
}

/// What a pick aims at: a body (evaluation, planning from the truth), or the pose a request
/// carried (the robot server, which knows only what the client sent): the body nearest it when
/// the jaws close.
#[derive(Debug, Clone, Copy)]
pub enum Aim {
    Body(RigidBodyHandle),
    Pose(Isometry3<f64>),
}

/// A scene in the physics world with the arm in it.
pub struct PickCell<'a> {
    pub scn: &'a Scenario,
    pub work: &'a Workcell,
    pub cell: Cell,
    pub arm: SimArm,
    /// (object id, model, body) for every object.
    pub objects: Vec<(u32, String, RigidBodyHandle)>,
    pub simulated_s: f64,
    /// The bin (index into the world's bins) a pick is judged against: the first unless told.
    pub bin: usize,
    /// Picks the arm has carried out so far (the robot's own count, for where over the bin it
    /// drops the next part).
    pub released: usize,
}

impl<'a> PickCell<'a> {
    /// The settled `scene` with the arm at [`HOME`].
    pub fn new(scn: &'a Scenario, work: &'a Workcell, scene: &Scene) -> Result<PickCell<'a>> {
        let statics = static_boxes(&scn.world);
        let mut cell = Cell::new(&scn.world.physics, &statics);
        sim::arm::configure_for_grasping(&mut cell);
        let objects = scene
            .objects
            .iter()
            .map(|o| {
                let body = cell.add_object(&scn.library.models[&o.model], &o.world_from_model);
                sim::arm::hold_without_ccd(&mut cell, body);
                (o.id, o.model.clone(), body)
            })
            .collect();
        let spec = scn.world.robot.as_ref().and_then(|r| r.as_built.as_ref());
        let built = sim::realism::ArmAsBuilt::new(spec, &scn.world.effects(), scn.world.as_built_seed);
        let arm = SimArm::insert(&mut cell, &work.urdf, &work.world_from_base, &HOME, 0.0, built.as_ref())?;
        let mut pc = PickCell { scn, work, cell, arm, objects, simulated_s: 0.0, bin: 0, released: 0 };
        pc.run_for(HOLD_S);
        Ok(pc)
    }

    fn dt(&self) -> f64 {
        self.cell.world.integration_parameters.dt as f64
    }

    fn step(&mut self) {
        self.cell.world.step();
        self.simulated_s += self.dt();
    }

    pub fn run_for(&mut self, seconds: f64) {
        for _ in 0..(seconds / self.dt()).ceil() as usize {
            self.step();
        }
    }

    fn body(&self, id: u32) -> Result<(String, RigidBodyHandle)> {
        self.objects
            .iter()
            .find(|(i, _, _)| *i == id)
            .map(|(_, m, b)| (m.clone(), *b))
            .ok_or_else(|| anyhow!("no object {id} in the scene (objects are numbered 1..={})", self.objects.len()))
    }

    /// The pick request for object `id`, from the objects' current (true) poses.
    pub fn request(&self, id: u32, seed: u64) -> Result<PickRequest> {
        let base_from_world = self.work.world_from_base.inverse();
        let mut obstacles = static_obstacles(self.scn, self.work);
        let mut target = None;
        for (oid, model, body) in &self.objects {
            let o = Obstacle {
                name: format!("object {oid} ({model})"),
                shape: collision_shape(&self.scn.library.models[model]),
                base_from_shape: base_from_world * self.cell.pose(*body),
            };
            if *oid == id { target = Some(o) } else { obstacles.push(o) }
        }
        let target = target.ok_or_else(|| anyhow!("no object {id}"))?;
        let (model_name, _) = self.body(id)?;
        let model = &self.scn.library.models[&model_name];
        let grasps = grasp_candidates(model, &target.base_from_shape);
        let target_com = target.base_from_shape * model.mass.centre_of_mass;
        let bin =
            self.scn.world.bins.first().ok_or_else(|| anyhow!("{}: no bin to place into", self.scn.path.display()))?;
        Ok(PickRequest {
            grasps,
            target,
            target_com,
            obstacles,
            place: place_target(self.work, bin, self.released),
            start: self.arm.joints(&self.cell),
            seed,
        })
    }

    /// Plans and executes the pick of object `id` into the first bin.
    pub fn pick(&mut self, id: u32, seed: u64) -> Result<PickOutcome> {
        self.body(id)?;
        let req = self.request(id, seed)?;
        let plan = plan_pick(&self.work.arm, &self.work.ik, &req);
        self.run_plan(id, plan)
    }

    /// Executes a pick plan for object `id` (or reports why there is none) and judges it.
    pub fn run_plan(&mut self, id: u32, plan: Result<PickPlan, robot::pick::PickError>) -> Result<PickOutcome> {
        let (_, body) = self.body(id)?;
        Ok(self.run_plan_on(Aim::Body(body), plan))
    }

    /// Executes a pick plan aimed at `aim` and judges it from the physics. A failed pick leaves
    /// the gripper open and lifted clear.
    pub fn run_plan_on(&mut self, aim: Aim, plan: Result<PickPlan, robot::pick::PickError>) -> PickOutcome {
        let start_s = self.simulated_s;
        let mut out = PickOutcome {
            object: 0,
            model: String::new(),
            result: "unplanned".into(),
            placed: false,
            held: false,
            detail: None,
            grasp: None,
            simulated_s: 0.0,
            max_tracking_error: 0.0,
            worst_tracking_step: None,
            closed_opening_mm: None,
            grasp_width_mm: None,
            grip_past_com_mm: None,
            lifted_instead: None,
        };
        if let Aim::Body(body) = aim {
            self.name_object(body, &mut out);
        }
        let plan = match plan {
            Ok(p) => p,
            Err(e) => {
                out.detail = Some(e.to_string());
                return out;
            }
        };
        out.grasp = Some(plan.grasp_index);
        out.grasp_width_mm = Some(plan.grasp.width * 1e3);
        out.grip_past_com_mm = Some(plan.grip_past_com_m * 1e3);
        self.execute(&plan, aim, &mut out);
        self.judge_wrong_part(&mut out);
        if !out.placed {
            tracing::debug!(object = out.object, model = %out.model, result = %out.result, detail = ?out.detail, "pick failed");
        }
        self.released += 1;
        if !out.placed {
            self.recover();
        }
        out.simulated_s = self.simulated_s - start_s;
        out
    }

    fn name_object(&self, body: RigidBodyHandle, out: &mut PickOutcome) {
        if let Some((id, model, _)) = self.objects.iter().find(|(_, _, b)| *b == body) {
            (out.object, out.model) = (*id, model.clone());
        }
    }

    /// The object whose centre of mass lies between the finger pads, the nearest the tool
    /// centre point if several do.
    fn body_between_fingers(&self) -> Option<RigidBodyHandle> {
        let gripper = self.arm.world_from_gripper(&self.cell);
        let distance = |b: RigidBodyHandle| {
            let com = self.cell.world.bodies[b].center_of_mass();
            (gripper.translation.vector - Vector3::new(com.x as f64, com.y as f64, com.z as f64)).norm()
        };
        self.objects
            .iter()
            .map(|(_, _, b)| *b)
            .filter(|b| self.between_fingers(*b))
            .min_by(|a, b| distance(*a).total_cmp(&distance(*b)))
    }

    fn execute(&mut self, plan: &PickPlan, aim: Aim, out: &mut PickOutcome) {
        let height = |cell: &Cell, b: RigidBodyHandle| cell.pose(b).translation.z;
        let mut target = match aim {
            Aim::Body(b) => Some((b, height(&self.cell, b))),
            Aim::Pose(_) => None,
        };
        let mut left_early = false;
        for step in &plan.steps {
            match &step.action {
                Action::Move(traj) => {
                    let err = self.follow(traj);
                    if err > out.max_tracking_error {
                        out.max_tracking_error = err;
                        out.worst_tracking_step = Some(step.label.to_string());
                    }
                }
                Action::Grip { opening } => self.grip(*opening),
            }
            match step.label {
                "close" => {
                    let opening = self.arm.opening(&self.cell);
                    out.closed_opening_mm = Some(opening * 1e3);
                    if let Some(b) = self.gripped_instead(aim, out) {
                        target = Some((b, height(&self.cell, b)));
                    }
                    if opening < 0.2 * plan.grasp.width || target.is_none() {
                        return fail(out, "miss", format!("the fingers closed to {:.1} mm on nothing", opening * 1e3));
                    }
                }
                "lift" => {
                    let Some((body, z0)) = target else { return };
                    let rise = height(&self.cell, body) - z0;
                    out.held = self.between_fingers(body) && rise > LIFTED_FRACTION * robot::pick::LIFT_M;
                    if !out.held {
                        return fail(out, "slip", format!("the object rose {:.0} mm with the gripper", rise * 1e3));
                    }
                }
                // Where it comes to rest decides: an object that leaves the jaws over the bin
                // still lands in it.
                "lower" if target.is_some_and(|(b, _)| !self.between_fingers(b)) => left_early = true,
                _ => {}
            }
        }
        let Some((body, _)) = target else { return };
        self.run_until_rest(body);
        let why_not = self.why_not_in(body, self.bin);
        out.placed = why_not.is_none();
        let p = self.cell.pose(body).translation.vector;
        let at = format!("it came to rest at ({:.3}, {:.3}, {:.3})", p.x, p.y, p.z);
        match (why_not, left_early) {
            (None, false) => out.result = "placed".into(),
            (None, true) => {
                out.result = "placed".into();
                out.detail = Some("it left the jaws on the way, and landed in the bin".into());
            }
            (Some(why), true) => {
                fail(out, "drop", format!("the object left the gripper on the way to the bin; {at}: {why}"))
            }
            (Some(why), false) => fail(out, "outside bin", format!("{at}: {why}")),
        }
    }

    /// When the jaws close: the body aimed at (`aim`'s, or the one nearest the pose it carried)
    /// is named in `out`; the body between the fingers is returned when the pick should follow
    /// it instead (the server's aim, which names no body; or another body than the one aimed
    /// at, which `out.lifted_instead` then names).
    fn gripped_instead(&self, aim: Aim, out: &mut PickOutcome) -> Option<RigidBodyHandle> {
        let intended = match aim {
            Aim::Body(b) => Some(b),
            Aim::Pose(p) => aimed_at(&self.cell, self.objects.iter().map(|(_, _, b)| *b), &p),
        };
        if let Some(b) = intended {
            self.name_object(b, out);
        }
        let gripped = intended.filter(|b| self.between_fingers(*b)).or_else(|| self.body_between_fingers())?;
        if intended.is_some_and(|i| i != gripped) {
            out.lifted_instead = self.objects.iter().find(|(_, _, b)| *b == gripped).map(|(id, _, _)| *id);
        }
        (matches!(aim, Aim::Pose(_)) || out.lifted_instead.is_some()).then_some(gripped)
    }

    /// A pick that lifted another body than the one aimed at is a `wrong part`, wherever that
    /// body came to rest.
    fn judge_wrong_part(&self, out: &mut PickOutcome) {
        let Some(other) = out.lifted_instead else { return };
        let then = match &out.detail {
            Some(d) => format!("{}: {d}", out.result),
            None => out.result.clone(),
        };
        out.placed = false;
        out.result = "wrong part".into();
        out.detail = Some(format!(
            "it lifted object {other} where it aimed at object {} ({}); then {then}",
            out.object, out.model
        ));
    }

    /// After a failed pick: opens the gripper and lifts straight up on the zed joint, which
    /// leaves whatever the gripper was near and gives the next plan a free start.
    fn recover(&mut self) {
        self.grip(self.work.arm.max_opening());
        let q = self.arm.joints(&self.cell);
        let mut up = q;
        up[0] = (q[0] + robot::pick::LIFT_M).min(self.work.arm.upper()[0]);
        let limits = robot::trajectory::Limits {
            velocity: self.work.arm.max_velocity(),
            acceleration: self.work.arm.max_acceleration(),
        };
        self.follow(&robot::trajectory::Trajectory::piecewise(&[q, up], &limits.scaled(robot::pick::NEAR_SPEED)));
    }

    /// Runs a trajectory through the joint motors; the worst tracking error.
    pub fn follow(&mut self, traj: &robot::trajectory::Trajectory) -> f64 {
        let n = (traj.duration() / self.dt()).ceil() as usize;
        let mut worst = 0.0f64;
        for i in 1..=n {
            let (q, qd) = traj.sample(i as f64 * self.dt());
            self.arm.command(&mut self.cell, &q, &qd);
            self.step();
            let actual = self.arm.joints(&self.cell);
            worst = worst.max((0..6).map(|k| (actual[k] - q[k]).abs()).fold(0.0, f64::max));
        }
        self.run_for(HOLD_S);
        worst
    }

    /// Commands the fingers and waits until they stop moving.
    pub fn grip(&mut self, opening: f64) {
        self.arm.grip(&mut self.cell, opening);
        let mut last = self.arm.opening(&self.cell);
        let (mut t, mut calm) = (0.0, 0.0);
        while t < GRIP_LIMIT_S && calm < 0.1 {
            self.step();
            t += self.dt();
            let now = self.arm.opening(&self.cell);
            calm = if (now - last).abs() < 1e-5 { calm + self.dt() } else { 0.0 };
            last = now;
        }
        self.run_for(HOLD_S);
    }

    fn run_until_rest(&mut self, body: RigidBodyHandle) {
        let mut calm = 0.0;
        let mut t = 0.0;
        while t < REST_LIMIT_S && calm < 0.25 {
            self.step();
            t += self.dt();
            let b = &self.cell.world.bodies[body];
            calm = if b.linvel().length() < 2e-3 && b.angvel().length() < 2e-2 { calm + self.dt() } else { 0.0 };
        }
    }

    /// The object's centre of mass lies between the finger pads (within reach of the tcp).
    fn between_fingers(&self, body: RigidBodyHandle) -> bool {
        let gripper = self.arm.world_from_gripper(&self.cell);
        let com = self.cell.world.bodies[body].center_of_mass();
        let c = gripper.inverse() * Point3::new(com.x as f64, com.y as f64, com.z as f64);
        let half = self.arm.opening(&self.cell) / 2.0 + 0.01;
        c.coords.norm() < HELD_RADIUS_M && c.y.abs() < half
    }

    /// Whether object `id` is in the bin now.
    pub fn in_bin(&self, id: u32) -> bool {
        self.body(id).is_ok_and(|(_, b)| self.inside_bin(b))
    }

    /// Every object where the simulation has it now, and whether it lies in a bin (evaluation's
    /// view).
    pub fn truth_objects(&self) -> Vec<crate::protocol::TruthObject> {
        self.objects
            .iter()
            .map(|(id, model, body)| crate::protocol::TruthObject {
                id: *id,
                model: model.clone(),
                world_from_model: crate::protocol::WirePose::new(None, &self.cell.pose(*body)),
                in_bin: self.inside_any_bin(*body),
            })
            .collect()
    }

    /// Whether `body` rests in any of the cell's bins.
    pub fn inside_any_bin(&self, body: RigidBodyHandle) -> bool {
        (0..self.scn.world.bins.len()).any(|k| self.why_not_in(body, k).is_none())
    }

    /// Whether `body` counts as placed in the target bin ([`super::judge`]'s rules).
    pub fn inside_bin(&self, body: RigidBodyHandle) -> bool {
        self.why_not_in(body, self.bin).is_none()
    }

    /// Why `body` does not count as placed in bin `k`, or `None` when it does.
    fn why_not_in(&self, body: RigidBodyHandle, k: usize) -> Option<String> {
        let Some(bin) = self.scn.world.bins.get(k) else { return Some(format!("the cell has no bin {k}")) };
        let Some((_, name, _)) = self.objects.iter().find(|(_, _, b)| *b == body) else {
            return Some("it is not a part of the scene".into());
        };
        let model = &self.scn.library.models[name];
        why_not_placed(&self.cell, &Part { body, model, fingers: &self.arm.finger_bodies }, bin)
    }
}

/// The cell's fixed boxes but the floor (table, bin walls) as the planner's obstacles, in the
/// base frame: what the robot knows of its cell without looking.
pub fn static_obstacles(scn: &Scenario, work: &Workcell) -> Vec<Obstacle> {
    let base_from_world = work.world_from_base.inverse();
    static_boxes(&scn.world)
        .into_iter()
        .filter(|b| b.name != "floor")
        .map(|b| {
            let h = b.half_extents;
            Obstacle {
                name: b.name.clone(),
                shape: parry3d::shape::SharedShape::cuboid(h.x as f32, h.y as f32, h.z as f32),
                base_from_shape: base_from_world * b.world_from_box,
            }
        })
        .collect()
}

/// The first bin's floor as a place target in the base frame.
pub fn place_target(work: &Workcell, bin: &sim::world::BinSpec, released: usize) -> PlaceTarget {
    let floor = Isometry3::translation(bin.centre_m[0], bin.centre_m[1], bin.wall_m);
    PlaceTarget {
        base_from_floor_centre: work.world_from_base.inverse() * floor,
        size_xy: [bin.size_m[0], bin.size_m[1]],
        released,
    }
}

fn fail(out: &mut PickOutcome, result: &str, detail: String) {
    out.result = result.into();
    out.detail = Some(detail);
}

/// Every model grasp and its equivalent holds, in the base frame, most nearly top-down first.
pub fn grasp_candidates(model: &Model, base_from_model: &Isometry3<f64>) -> Vec<GraspCandidate> {
    let mut out: Vec<GraspCandidate> = model
        .grasps
        .iter()
        .flat_map(|g| {
            grasp_variants(&(base_from_model * g.model_from_gripper))
                .map(|pose| GraspCandidate { base_from_gripper: pose, width: g.opening })
        })
        .collect();
    let downness = |g: &GraspCandidate| (g.base_from_gripper.rotation * Vector3::z()).z;
    out.sort_by(|a, b| downness(a).total_cmp(&downness(b)));
    out
}

/// Loads the scenario and its workcell, with context naming the world file.
pub fn load(path: &std::path::Path) -> Result<(Scenario, Workcell)> {
    let scn = Scenario::load(path)?;
    let work = Workcell::new(&scn)?;
    Ok((scn, work))
}

/// Passes over the table when clearing it: an object that could not be picked is tried again
/// once the others have gone.
pub const CLEARING_PASSES: usize = 3;

/// Clears the table: picks every object in turn, the highest first (as a heap needs), each
/// planned from the objects' poses at that moment; objects that fail are tried again in later
/// passes unless they came to rest inside the bin anyway. Every attempt is kept, object by object.
pub fn clear_scene(scn: &Scenario, work: &Workcell, scene: &Scene) -> Result<Vec<ObjectPicks>> {
    clear_cell(&mut PickCell::new(scn, work, scene)?, scene.seed)
}

/// [`clear_scene`] on a cell already made (whose state the caller may then look at); `seed`
/// seeds the planner.
pub fn clear_cell(cell: &mut PickCell, seed: u64) -> Result<Vec<ObjectPicks>> {
    let mut picks: Vec<ObjectPicks> =
        cell.objects.iter().map(|(id, _, _)| ObjectPicks { object: *id, attempts: Vec::new() }).collect();
    for pass in 0..CLEARING_PASSES {
        let mut todo: Vec<u32> = picks
            .iter()
            .filter(|p| p.last().is_none_or(|o| !o.placed && !cell.in_bin(p.object)))
            .map(|p| p.object)
            .collect();
        let mut progress = false;
        while !todo.is_empty() {
            let height =
                |id: &u32| cell.body(*id).map(|(_, b)| cell.cell.world.bodies[b].center_of_mass().z).unwrap_or(0.0);
            let next = *todo.iter().max_by(|a, b| height(a).total_cmp(&height(b))).expect("not empty");
            todo.retain(|&id| id != next);
            let seed = seed.wrapping_mul(31).wrapping_add(next as u64 + 1000 * pass as u64);
            let outcome = cell.pick(next, seed)?;
            progress |= outcome.placed;
            picks.iter_mut().find(|p| p.object == next).expect("every object listed").attempts.push(outcome);
        }
        if !progress {
            break;
        }
    }
    Ok(picks)
}

/// Every pick tried at one object while clearing a scene, in order: the last says how it ended.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectPicks {
    pub object: u32,
    pub attempts: Vec<PickOutcome>,
}

impl ObjectPicks {
    /// The pick that decided the object's fate, if any was tried.
    pub fn last(&self) -> Option<&PickOutcome> {
        self.attempts.last()
    }

    /// Whether the object ended in the bin.
    pub fn cleared(&self) -> bool {
        self.last().is_some_and(|o| o.placed)
    }
}

/// The scenario with its clutter replaced by one `model`, dropped over the same region.
pub fn single_object_scenario(scn: &Scenario, model: &str) -> Scenario {
    let mut single = scn.clone();
    single.world.objects.clear();
    if let Some(clutter) = &mut single.world.clutter {
        clutter.objects = vec![sim::world::ClutterItem { model: model.to_string(), count: 1 }];
    }
    single
}

/// Library models a pick evaluation uses: the parts, not the calibration tools, which are held
/// edge-on in the gripper (a 4 mm plate flat on the table leaves no room for fingertips under
/// its grasp).
pub fn pickable_models(scn: &Scenario) -> Vec<String> {
    scn.library.parts().map(|m| m.name.clone()).collect()
}
