//! Hand-eye calibration end to end in the simulated cell: a robot server in-process, the flag
//! handed in, carried to 20 poses, seen, located and solved; the result against the simulation's
//! truth (read here, after the solve, as evaluation does).
//!
//! The seeds are the first two of the reporting range (10001, 10002: never used to choose
//! anything). The limits are regression limits near what the calibration does today (`marvin
//! calibrate worlds/widgets.toml --seed S` for S in 10001-10010: 0.16-0.61 mm, 0.033-0.13 deg,
//! 15-19 of 20 poses used; these two seeds 0.60 mm / 0.096 deg and 0.16 mm / 0.033 deg; the
//! limits, 0.92 mm / 0.20 deg, are 1.5 times the worst of the ten), not the hand-eye issue's
//! targets (0.5 mm, 0.05 deg median), which it does not meet yet: the flag creeps ~0.7 mm in
//! the jaws during a calibration.

use marvin::calibrate::{CalibrateConfig, calibrate};
use marvin::client::Client;
use marvin::server::{CellConfig, Server, ServerConfig};
use marvin::truth::AskTruth;
use std::time::Duration;

fn calibrate_seed(seed: u64) -> (f64, f64, usize) {
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml");
    let cell = CellConfig { world: world.into(), seed: Some(seed), cam_from_base: None, expose_truth: true };
    let server = Server::start(ServerConfig::new(cell, "127.0.0.1:0".parse().unwrap())).unwrap();
    let mut client = Client::connect(&server.addr().to_string(), Duration::from_secs(5)).unwrap();
    client.hello(None).unwrap();
    let library = mesh::Library::load_default().unwrap();
    let config = CalibrateConfig { seed, ..CalibrateConfig::default() };
    let c = calibrate(&mut client, &library, &config, &mut |_, _| Ok(()), &mut |_| {}).unwrap();
    // Evaluation, after the fact.
    let truth = client.truth().unwrap().cam_from_base.to_isometry("truth").unwrap();
    assert!(client.status().unwrap().holding.is_none(), "the flag was stowed");
    let s = &c.solution.cam_from_base;
    let mm = (s.translation.vector - truth.translation.vector).norm() * 1e3;
    let deg = s.rotation.angle_to(&truth.rotation).to_degrees();
    (mm, deg, c.solution.used.iter().filter(|u| **u).count())
}

#[test]
fn calibration_finds_the_camera_within_regression_limits() {
    for seed in [10001, 10002] {
        let (mm, deg, used) = calibrate_seed(seed);
        eprintln!("seed {seed}: {mm:.3} mm, {deg:.4} deg, {used} sightings used");
        assert!(used >= 12, "seed {seed}: only {used} sightings used");
        assert!(mm < 0.92 && deg < 0.20, "seed {seed}: {mm:.3} mm, {deg:.4} deg from the truth");
    }
}
