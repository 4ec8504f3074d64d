//! Hand-eye calibration end to end in the simulated cell: a robot server in-process, the flag
//! handed in, carried to 20 poses, seen, located and solved; the result against the simulation's
//! truth (read here, after the solve, as evaluation does).
//!
//! The seeds are 360001-360003, a range never used for a choice (the test ran on 10001-10003
//! until that range had served for choices). The limits are the hand-eye issue's: every
//! calibration within twice the median targets (1.0 mm, 0.1 deg), their median within the targets
//! (0.5 mm, 0.05 deg), and the flag moving less than 0.1 mm in the jaws between the first and last
//! sighting: the numbers, not chosen from any measurement.
//!
//! Run on the ideal copy of the world (`worlds/ideal/`): these figures were measured in the ideal
//! cell and vision has not yet earned them in the realistic one (README, "The realistic cell").
//!
//! The hand-eye solution is tested alone here: vision sees through the cameras exactly as built,
//! which this test (not the run path) reads from the world file. Through cameras measured from
//! the board first, as `marvin run` does, `tests/run.rs` tests the whole.

use marvin::engine::calibrate::{CalibrateConfig, calibrate};
use marvin::engine::client::Client;
use marvin::server::{CellConfig, Server, ServerConfig};
use nalgebra::Isometry3;
use std::time::Duration;

struct Outcome {
    mm: f64,
    deg: f64,
    used: usize,
    /// How far the flag moved in the jaws between the first and last sighting (physics), mm.
    creep_mm: f64,
}

/// The cameras as built, with the left camera's frame as `cam` (the test's knowledge, not vision's).
fn exact_cameras(world: &str) -> mesh::StereoCalibration {
    let scn = sim::Scenario::load(std::path::Path::new(world)).unwrap();
    let rig = sim::imaging::Imaging::new(&scn.world).rig;
    assert!(rig.left.lens.distortion.is_none() && rig.right.lens.distortion.is_none(), "an ideal cell's lenses");
    let (left, right) = (rig.left.pinhole.clone(), rig.right.pinhole.clone());
    let cam_from_world = left.cam_from_world();
    mesh::StereoCalibration {
        left: mesh::PinholeCamera { world_from_cam: nalgebra::Isometry3::identity(), ..left },
        right: mesh::PinholeCamera { world_from_cam: cam_from_world * right.world_from_cam, ..right },
    }
}

fn calibrate_seed(seed: u64) -> Outcome {
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/ideal/widgets.toml");
    let cell =
        CellConfig { world: world.into(), seed: Some(seed), cam_from_base: None, expose_truth: false, cameras: None };
    let server = Server::start(ServerConfig::new(cell, "127.0.0.1:0".parse().unwrap())).unwrap();
    let mut client = Client::connect(&server.addr().to_string(), Duration::from_secs(5)).unwrap();
    client.hello(None).unwrap();
    let library = mesh::Library::load_default().unwrap();
    let config = CalibrateConfig { seed, cameras: Some(exact_cameras(world)), ..CalibrateConfig::default() };
    // Evaluation listens at each capture for where the flag sits in the gripper.
    let mut flag_in_gripper: Vec<Isometry3<f64>> = Vec::new();
    let mut after_capture = |_: &mut Client, _k: usize| -> anyhow::Result<()> {
        let held = server.truth()?.tool_in_gripper.expect("the flag is held during the calibration");
        flag_in_gripper.push(held.to_isometry("tool_in_gripper")?);
        Ok(())
    };
    let c = calibrate(&mut client, &library, &config, &mut after_capture, &mut |_| {}).unwrap();
    // Evaluation, after the fact.
    let truth = server.truth().unwrap().cam_from_base.to_isometry("truth").unwrap();
    assert!(client.status().unwrap().holding.is_none(), "the flag was stowed");
    let s = &c.solution.cam_from_base;
    let (first, last) = (flag_in_gripper.first().unwrap(), flag_in_gripper.last().unwrap());
    Outcome {
        mm: (s.translation.vector - truth.translation.vector).norm() * 1e3,
        deg: s.rotation.angle_to(&truth.rotation).to_degrees(),
        used: c.solution.used.iter().filter(|u| **u).count(),
        creep_mm: (last.translation.vector - first.translation.vector).norm() * 1e3,
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn calibration_meets_the_hand_eye_targets_and_the_flag_stays_put() {
    let outcomes: Vec<Outcome> = [360001, 360002, 360003].map(calibrate_seed).into();
    for (seed, o) in (360001..).zip(&outcomes) {
        eprintln!(
            "seed {seed}: {:.3} mm, {:.4} deg, {} sightings used, the flag moved {:.3} mm",
            o.mm, o.deg, o.used, o.creep_mm
        );
        assert!(o.used >= 12, "seed {seed}: only {} sightings used", o.used);
        assert!(o.mm <= 1.0 && o.deg <= 0.1, "seed {seed}: {:.3} mm, {:.4} deg from the truth", o.mm, o.deg);
        assert!(o.creep_mm < 0.1, "seed {seed}: the flag moved {:.3} mm in the jaws", o.creep_mm);
    }
    let mm = median(outcomes.iter().map(|o| o.mm).collect());
    let deg = median(outcomes.iter().map(|o| o.deg).collect());
    assert!(mm <= 0.5 && deg <= 0.05, "median of three: {mm:.3} mm, {deg:.4} deg");
}

/// A flag that leaves the jaws before its sightings settle the solution is handed in again and
/// the sightings start afresh. Realistic `widgets.toml` tuning seed 108, through cameras
/// measured from the board first (in a cell of their own, so that the flag's is the cell's first
/// handover, as with `marvin run --cameras`): the flag left the jaws on the way to the first
/// pose, and the calibration failed with no sighting at all. Now it is handed in again and the
/// calibration solves within the bars `marvin run` picks by (3 mm, 0.3 deg,
/// `engine::calibrate::UNCERTAIN_MM`, `UNCERTAIN_DEG`), judged against the truth, with the flag
/// staying put in the jaws from its first sighting kept.
#[test]
fn a_flag_that_leaves_the_jaws_is_handed_in_again() {
    let dir = std::env::temp_dir().join(format!("marvin_flag_again_{}", std::process::id()));
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml");
    let marvin = |args: &[&str], out: &std::path::Path| {
        let run = std::process::Command::new(env!("CARGO_BIN_EXE_marvin")).args(args).arg("--out").arg(out).output();
        let run = run.unwrap();
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        run.stdout
    };
    marvin(&["calibrate", "cameras", world, "--seed", "108"], &dir.join("cams"));
    let cameras = dir.join("cams/cameras.json");
    let stdout = marvin(
        &["calibrate", world, "--seed", "108", "--json", "--cameras", cameras.to_str().unwrap()],
        &dir.join("hand_eye.json"),
    );
    let doc: serde_json::Value = serde_json::from_slice(&stdout).unwrap();
    let notes: Vec<&str> = doc["sightings"].as_array().unwrap().iter().map(|s| s["note"].as_str().unwrap()).collect();
    assert!(notes.iter().any(|n| n.contains("left the jaws") && n.contains("handed in again")), "{notes:?}");
    let (mm, deg) = (doc["error"]["translation_mm"].as_f64().unwrap(), doc["error"]["rotation_deg"].as_f64().unwrap());
    assert!(
        mm < marvin::engine::calibrate::UNCERTAIN_MM && deg < marvin::engine::calibrate::UNCERTAIN_DEG,
        "{mm:.2} mm, {deg:.3} deg"
    );
    let creep = doc["flag_creep_mm"].as_f64().unwrap();
    assert!(creep < 0.1, "the flag moved {creep:.3} mm in the jaws after it was handed in again");
    let _ = std::fs::remove_dir_all(&dir);
}
