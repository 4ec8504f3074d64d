//! The arm end to end: the simulated arm agrees with the kinematics the planner uses, physical
//! picks succeed at the rates on a few seeded scenes, failures are caught by the physics
//! and never counted as successes, and a world whose robot URDF is missing is refused.
//!
//! Run on the ideal copy of the world (`worlds/ideal/`): these figures were measured in the ideal
//! cell and vision has not yet earned them in the realistic one (README, "The realistic cell").

use marvin::server::pick::{Aim, PickCell, clear_scene, load, pickable_models, single_object_scenario};
use nalgebra::{Isometry3, Translation3, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use robot::pick::{Action, GraspCandidate, plan_pick};
use sim::Scene;
use std::path::Path;

fn world() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/ideal/widgets.toml"))
}

#[test]
fn the_simulated_arm_stands_where_the_planner_computes_it() {
    let (scn, work) = load(world()).unwrap();
    let mut rng = StdRng::seed_from_u64(5);
    let (lo, hi) = (work.arm.lower(), work.arm.upper());
    for _ in 0..20 {
        let q: robot::Joints = std::array::from_fn(|k| rng.random_range(lo[k]..hi[k]));
        let mut cell = sim::physics::Cell::new(&scn.world.physics, &[]);
        let arm = sim::arm::SimArm::insert(&mut cell, &work.urdf, &work.world_from_base, &q, 0.03, None).unwrap();
        let simulated = arm.world_from_gripper(&cell);
        let computed: Isometry3<f64> = work.world_from_base * work.arm.base_from_gripper(&q);
        let dp = (simulated.translation.vector - computed.translation.vector).norm();
        assert!(dp < 1e-5 && simulated.rotation.angle_to(&computed.rotation) < 1e-5, "{q:?}: {dp} m apart");
        assert!((arm.opening(&cell) - 0.03).abs() < 1e-6);
    }
}

/// An arm built off its drawing (the realistic preset's seeded joint offsets and link errors)
/// stands, at a commanded joint vector, where the forward kinematics of the as-built URDF put
/// it (the planner's kinematics, `robot::arm`, an independent computation from rapier's
/// multibody), not where the drawing's do; its encoders read the command to their counts.
#[test]
fn an_arm_as_built_stands_where_its_own_kinematics_put_it_not_its_drawings() {
    let realistic = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml"));
    let (scn, work) = load(realistic).unwrap();
    let spec = scn.world.robot.as_ref().and_then(|r| r.as_built.as_ref());
    let built = sim::realism::ArmAsBuilt::new(spec, &scn.world.effects(), scn.world.as_built_seed).unwrap();
    let text = built.urdf_text(&work.urdf).unwrap();
    let as_built = robot::arm::Arm::from_urdf_str(&text, "as built").unwrap();
    let mut rng = StdRng::seed_from_u64(7);
    let (lo, hi) = (work.arm.lower(), work.arm.upper());
    let mut off_drawing = Vec::new();
    for _ in 0..10 {
        let q: robot::Joints = std::array::from_fn(|k| rng.random_range(lo[k]..hi[k]));
        let mut cell = sim::physics::Cell::new(&scn.world.physics, &[]);
        let arm =
            sim::arm::SimArm::insert(&mut cell, &work.urdf, &work.world_from_base, &q, 0.03, Some(&built)).unwrap();
        let simulated = arm.world_from_gripper(&cell);
        let expected = work.world_from_base * as_built.base_from_gripper(&q);
        let dp = (simulated.translation.vector - expected.translation.vector).norm();
        assert!(dp < 1e-5 && simulated.rotation.angle_to(&expected.rotation) < 1e-5, "{q:?}: {dp} m apart");
        let drawing = work.world_from_base * work.arm.base_from_gripper(&q);
        off_drawing.push((simulated.translation.vector - drawing.translation.vector).norm());
        for (k, (read, commanded)) in arm.joints(&cell).iter().zip(&q).enumerate() {
            let count = if k == 0 {
                1.0 / built.encoder_counts_per_m
            } else {
                std::f64::consts::TAU / built.encoder_counts_per_rev
            };
            assert!((read - commanded).abs() <= count / 2.0 + 1e-9, "joint {k}: read {read}, commanded {commanded}");
            assert!(((read / count).round() * count - read).abs() < 1e-12, "joint {k}: {read} is no whole count");
        }
    }
    // 0.1 deg of offset on a 0.5 m reach and 0.2 mm per link: the gripper stands a fraction of a
    // millimetre to a millimetre or two off where the drawing says.
    let worst = off_drawing.iter().copied().fold(0.0, f64::max);
    assert!(worst > 2e-4 && worst < 5e-3, "off the drawing by {off_drawing:?} m");
}

/// How far the closed jaws may be from the grasp's width, mm (measured at most 0.35).
const JAW_SINK_MM: f64 = 0.6;

#[test]
fn single_objects_are_picked_and_placed() {
    let (scn, work) = load(world()).unwrap();
    let mut outcomes = Vec::new();
    for model in pickable_models(&scn) {
        let one = single_object_scenario(&scn, &model);
        for seed in 360001..=360003 {
            let scene = Scene::settle(&one, seed);
            let out = PickCell::new(&one, &work, &scene).unwrap().pick(1, seed).unwrap();
            if out.placed {
                // Held between the fingers, closed to the width the grasp says: rapier's soft
                // contacts let each 20 N pad sink a little into a part (measured over these 21
                // picks: 0.07-0.35 mm under the width; the grasps' widths differ by 5 mm or more,
                // so closing on another pair of faces fails).
                let (closed, width) = (out.closed_opening_mm.unwrap(), out.grasp_width_mm.unwrap());
                assert!(
                    out.held && (width - closed).abs() <= JAW_SINK_MM,
                    "closed to {closed:.2} mm on {width:.2}: {out:?}"
                );
            }
            outcomes.push(out);
        }
    }
    let placed = outcomes.iter().filter(|o| o.placed).count();
    let failed: Vec<_> = outcomes.iter().filter(|o| !o.placed).collect();
    assert!(placed as f64 >= 0.95 * outcomes.len() as f64, "{placed}/{}: {failed:?}", outcomes.len());
}

/// Two clutter scenes, 360001-360002 (never used to choose anything; the test ran on 10001-10002
/// until that range had served for choices), cleared object by object from true poses and
/// judged strictly (`src/server/judge.rs`). Every attempt is kept: the first attempts are judged
/// as well as how each object ended. On 10001-10002 all 14 were cleared at their first pick; the
/// limits let one part stay and two first picks fail (over 20 scenes of 10001- 98.6% were cleared
/// and 95.0% went at the first pick).
#[test]
fn clutter_is_cleared_into_the_bin() {
    let (scn, work) = load(world()).unwrap();
    let mut objects = Vec::new();
    for seed in [360001, 360002] {
        objects.extend(clear_scene(&scn, &work, &Scene::settle(&scn, seed)).unwrap());
    }
    assert_eq!(objects.len(), 14, "every object listed");
    let cleared = objects.iter().filter(|o| o.cleared()).count();
    let first = objects.iter().filter(|o| o.attempts.first().is_some_and(|a| a.placed)).count();
    let failed: Vec<_> = objects.iter().flat_map(|o| &o.attempts).filter(|a| !a.placed).collect();
    assert!(objects.iter().all(|o| !o.attempts.is_empty()), "an object never tried");
    assert!(cleared as f64 >= 0.90 * 14.0, "{cleared}/14 cleared: {failed:?}");
    assert!(first as f64 >= 0.85 * 14.0, "{first}/14 at the first attempt: {failed:?}");
}

/// The robot server knows only the pose a request carried: a plan that lifts another part than
/// the one nearest that pose is a `wrong part`, not a success, though the part it lifted lands
/// in the bin. (Tuning seed 3: the highest part is picked by its own plan, while the request
/// names the part farthest from it.)
#[test]
fn a_pick_that_lifts_another_part_than_the_one_aimed_at_is_a_wrong_part() {
    let (scn, work) = load(world()).unwrap();
    let mut cell = PickCell::new(&scn, &work, &Scene::settle(&scn, 3)).unwrap();
    let centre = |b| cell.cell.pose(b).translation.vector;
    let &(lifted, _, lifted_body) = cell.objects.iter().max_by(|a, b| centre(a.2).z.total_cmp(&centre(b.2).z)).unwrap();
    let &(aimed, _, aimed_body) = cell
        .objects
        .iter()
        .max_by(|a, b| {
            (centre(a.2) - centre(lifted_body)).norm().total_cmp(&(centre(b.2) - centre(lifted_body)).norm())
        })
        .unwrap();
    let plan = plan_pick(&work.arm, &work.ik, &cell.request(lifted, 3).unwrap());
    let aimed_pose = cell.cell.pose(aimed_body);
    let out = cell.run_plan_on(Aim::Pose(aimed_pose), plan);
    assert_eq!(out.result, "wrong part", "{out:?}");
    assert!(!out.placed);
    assert_eq!((out.object, out.lifted_instead), (aimed, Some(lifted)), "{out:?}");
    assert!(cell.in_bin(lifted), "the part lifted was carried to the bin all the same: {out:?}");
    assert!(!cell.in_bin(aimed));
}

/// The plan says how deep its fingertips reach past the part's centre of mass: for a block
/// lying flat, taken from straight above as written and 14 mm shallower, the depth below its
/// centre of mass of a point 5 mm below the tool centre point (the URDF's fingertips).
#[test]
fn a_plan_says_how_far_its_fingertips_reach_past_the_centre_of_mass() {
    let (scn, work) = load(world()).unwrap();
    let one = single_object_scenario(&scn, "block");
    let cell = PickCell::new(&one, &work, &Scene::settle(&one, 2)).unwrap();
    let mut request = cell.request(1, 2).unwrap();
    let written = request.grasps[0];
    let approach = written.base_from_gripper.rotation * Vector3::z();
    assert!(approach.z < -0.999, "taken from straight above: {approach}");
    let shallow = GraspCandidate {
        base_from_gripper: Translation3::from(-0.014 * approach) * written.base_from_gripper,
        ..written
    };
    let below_com =
        |plan: &robot::pick::PickPlan| request.target_com.z - (plan.grasp.base_from_gripper.translation.z - 0.005);
    let plan = plan_pick(&work.arm, &work.ik, &request).unwrap();
    assert!((plan.grip_past_com_m - below_com(&plan)).abs() < 1e-9, "{} {}", plan.grip_past_com_m, below_com(&plan));
    // The block's grasp holds it at its middle: the fingertips 5 mm below it.
    assert!((plan.grip_past_com_m - 0.005).abs() < 1e-6, "{}", plan.grip_past_com_m);
    request.grasps = vec![shallow];
    let plan = plan_pick(&work.arm, &work.ik, &request).unwrap();
    assert!((plan.grip_past_com_m - below_com(&plan)).abs() < 1e-9, "{} {}", plan.grip_past_com_m, below_com(&plan));
    assert!(plan.grip_past_com_m <= 0.005 - 0.014 + 1e-6, "{}", plan.grip_past_com_m);
}

#[test]
fn a_grip_that_never_closes_is_a_slip_not_a_success() {
    let (scn, work) = load(world()).unwrap();
    let one = single_object_scenario(&scn, "block");
    let scene = Scene::settle(&one, 2);
    let mut cell = PickCell::new(&one, &work, &scene).unwrap();
    let mut plan = plan_pick(&work.arm, &work.ik, &cell.request(1, 2).unwrap()).unwrap();
    // Sabotage: "close" leaves the jaws as wide open as they came in.
    let open = plan.steps.iter().find_map(|s| match s.action {
        Action::Grip { opening } if s.label == "open" => Some(opening),
        _ => None,
    });
    for step in &mut plan.steps {
        if step.label == "close" {
            step.action = Action::Grip { opening: open.unwrap() };
        }
    }
    let out = cell.run_plan(1, Ok(plan)).unwrap();
    assert!(!out.placed && !out.held, "{out:?}");
    assert_eq!(out.result, "slip", "{out:?}");
    assert!(!cell.in_bin(1), "the block stayed on the table");
}

#[test]
fn a_world_whose_robot_urdf_is_missing_is_refused_with_the_line() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("missing_urdf");
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(world()).unwrap().replace("../urdf/umi_rtx.urdf", "nowhere.urdf");
    let line = text.lines().position(|l| l.contains("nowhere.urdf")).unwrap() + 1;
    let path = dir.join("w.toml");
    std::fs::write(&path, text).unwrap();
    let err = load(&path).err().expect("refused").to_string();
    assert!(
        err.contains(&format!("w.toml:{line}")) && err.contains("robot.urdf") && err.contains("nowhere.urdf"),
        "{err}"
    );
}

#[test]
fn the_flag_tool_is_held_in_the_gripper_while_the_arm_moves() {
    let (scn, work) = load(world()).unwrap();
    let tool = robot::tool::Tool::from_urdf_file(&work.urdf.with_file_name("flag_tool.urdf")).unwrap();
    // The tool's URDF and the flag model agree on where the gripper holds it.
    let grasp = scn.library.get("flag").unwrap().grasps[0];
    let model_from_tool_grip = grasp.model_from_gripper.inverse() * tool.tool_from_gripper;
    assert!(model_from_tool_grip.translation.vector.norm() < 1e-9 && model_from_tool_grip.rotation.angle() < 1e-9);

    let mut cell = sim::physics::Cell::new(&scn.world.physics, &[]);
    sim::arm::configure_for_grasping(&mut cell);
    let start = [0.6, 0.3, 1.2, 0.0, 0.0, 0.0];
    let arm = sim::arm::SimArm::insert(&mut cell, &work.urdf, &work.world_from_base, &start, 0.012, None).unwrap();
    let gripper_from_flag = tool.tool_from_gripper.inverse();
    let flag = cell.add_object(scn.library.get("flag").unwrap(), &(arm.world_from_gripper(&cell) * gripper_from_flag));
    arm.grip(&mut cell, 0.0);
    sim::arm::hold_without_ccd(&mut cell, flag);
    for _ in 0..120 {
        cell.world.step();
    }
    // Closed on the 4 mm plate (rapier's soft contacts let 20 N pads sink about 0.5 mm each into
    // a thin plate's faces; on the 15-50 mm parts it is 0.1-0.2 mm).
    let opening = arm.opening(&cell);
    assert!(opening > 0.0025 && opening < 0.0043, "closed on the 4 mm plate: {opening}");
    // Swing the arm, tilt and roll the wrist: calibration poses.
    let limits =
        robot::trajectory::Limits { velocity: work.arm.max_velocity(), acceleration: work.arm.max_acceleration() };
    let poses = [start, [0.5, -0.4, 1.6, 0.8, 0.6, 1.2], [0.7, 0.5, 0.9, -0.5, -0.7, -1.0]];
    let traj = robot::trajectory::Trajectory::piecewise(&poses, &limits.scaled(0.8));
    let dt = cell.world.integration_parameters.dt as f64;
    let held = |cell: &sim::physics::Cell| arm.world_from_gripper(cell).inverse() * cell.pose(flag);
    let before = held(&cell);
    for i in 1..=(traj.duration() / dt).ceil() as usize {
        let (q, qd) = traj.sample(i as f64 * dt);
        arm.command(&mut cell, &q, &qd);
        cell.world.step();
    }
    let after = held(&cell);
    let moved = (after.translation.vector - before.translation.vector).norm();
    let turned = after.rotation.angle_to(&before.rotation).to_degrees();
    eprintln!("the flag moved {:.2} mm and turned {turned:.2} deg in the gripper", moved * 1e3);
    // Held, but not rigidly: under these swings the plate creeps about 2 mm and turns about 2 deg
    // in the jaws (rapier's friction on multibody links is not perfectly static). Hand-eye
    // calibration needs to know: the flag pose in the gripper is good to a few millimetres.
    assert!(arm.opening(&cell) > 0.0025, "the jaws closed on nothing");
    assert!(moved < 0.005 && turned < 5.0, "{moved} m, {turned} deg");
}
