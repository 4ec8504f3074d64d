//! The whole loop, as `marvin run --cameras` runs it: cameras measured from the board once, then
//! for two seeded scenes a robot server in-process, a hand-eye calibration through the measured
//! cameras, then the cycles of capture, front end, matcher, choice and pick over
//! the socket until nothing more is located. The table must end clear (checked against the
//! simulation's truth, read after the run).
//!
//! The scenes are 360001 and 360002, never used to choose anything, not seeds picked because they
//! cleared (the test ran on 10001-10002 until that range had served for choices; there, seed
//! 10002 was looked into when it failed, see `measured_cameras`). Not every scene ends clear:
//! `marvin eval run worlds/ideal/widgets.toml --scenes 100 --seed 350001`, one calibration
//! shared, cleared 99.7% of objects (the realistic world 98.4%).
//!
//! Run on the ideal copy of the world (`worlds/ideal/`): these figures were measured in the ideal
//! cell and vision has not yet earned them in the realistic one (README, "The realistic cell").

use marvin::engine::calibrate::{CalibrateConfig, calibrate};
use marvin::engine::calibrate_cameras::{CameraCalibConfig, calibrate_cameras};
use marvin::engine::client::Client;
use marvin::engine::run::{RunConfig, Stop, run};
use marvin::protocol::WirePose;
use marvin::server::{CellConfig, Server, ServerConfig};
use std::time::Duration;

fn server(seed: u64) -> (Server, Client, f64) {
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/ideal/widgets.toml");
    let cell =
        CellConfig { world: world.into(), seed: Some(seed), cam_from_base: None, expose_truth: false, cameras: None };
    let server = Server::start(ServerConfig::new(cell, "127.0.0.1:0".parse().unwrap())).unwrap();
    let mut client = Client::connect(&server.addr().to_string(), Duration::from_secs(5)).unwrap();
    let table_top = client.hello(None).unwrap().table_top_base_m.unwrap();
    (server, client, table_top)
}

/// The cameras as measured once, in a cell of their own (seed 360001's), from the board: as a
/// cell's cameras are calibrated before runs and each run reads the file (`marvin run
/// --cameras`). Said plainly: this shape was chosen after seed 10002 failed with the cameras
/// calibrated in the run's own cell (a board knocked out of the jaws fell into the clutter and
/// swept a block 18 cm), so seed 10002 has been looked at for this test; the limits were not
/// changed.
fn measured_cameras(library: &mesh::Library) -> mesh::StereoCalibration {
    let (s, mut c, table_top) = server(360001);
    // The server tells nothing of its cameras: they are measured.
    assert!(c.capture().unwrap().calibration.is_none(), "the server tells nothing of its cameras");
    let config = CameraCalibConfig { seed: 360001, ..CameraCalibConfig::default() };
    let cameras = calibrate_cameras(&mut c, table_top, library, &config, false, &mut |_| {}).unwrap();
    s.stop();
    cameras.stereo_calibration()
}

#[test]
fn the_table_is_cleared_from_what_the_cameras_see() {
    let library = mesh::Library::load_default().unwrap();
    let cameras = measured_cameras(&library);
    for seed in [360001, 360002] {
        let (s, mut c, _) = server(seed);
        // As `marvin run --cameras` does: the hand-eye transform through the measured cameras
        // first, then pick.
        let config = CalibrateConfig { seed, cameras: Some(cameras.clone()), ..CalibrateConfig::default() };
        let calibration = calibrate(&mut c, &library, &config, &mut |_, _| Ok(()), &mut |_| {}).unwrap();
        let cam_from_base = calibration.solution.cam_from_base;
        c.set_hand_eye(WirePose::new(None, &cam_from_base)).unwrap();
        let on_table = s.truth().unwrap().objects.len();
        let run_config = RunConfig { cameras: Some(cameras.clone()), ..RunConfig::default() };
        let report =
            run(&mut c, &library, &run_config, &cam_from_base, &mut |_, _, _| Ok(()), &mut |_| Ok(())).unwrap();
        let truth = s.truth().unwrap();
        let left: Vec<String> =
            truth.objects.iter().filter(|o| !o.in_bin).map(|o| format!("{} {}", o.id, o.model)).collect();
        eprintln!("seed {seed}: {} cycles, left on the table: {left:?}", report.cycles.len());
        for (k, c) in report.cycles.iter().enumerate() {
            let chosen = c.chosen.map(|i| c.located[i].model.as_str());
            let outcome = c.outcome.as_ref().map(|o| o.as_ref().map(|r| (r.outcome, r.detail.clone())));
            eprintln!("  cycle {}: {chosen:?}: {outcome:?}", k + 1);
        }
        for o in &truth.objects {
            eprintln!(
                "  object {} {} at {:?}, in the bin: {}",
                o.id, o.model, o.world_from_model.translation_m, o.in_bin
            );
        }
        assert_eq!(report.stop, Stop::NothingLocated, "seed {seed}");
        assert!(left.is_empty(), "seed {seed}: {} of {on_table} left on the table: {left:?}", left.len());
        s.stop();
    }
}
