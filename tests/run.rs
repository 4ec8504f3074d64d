//! The whole loop, as `marvin run` runs it: a robot server in-process, one hand-eye calibration,
//! then for two seeded scenes the cycles of capture, front end, matcher, choice and pick over
//! the socket until nothing more is located. The table must end clear (checked against the
//! simulation's truth, read after the run).
//!
//! Not every scene ends clear (`marvin eval run worlds/widgets.toml --scenes 20`: 95% of objects
//! cleared; seed 2 leaves a wedge on the table). Seeds 5 and 6 did end clear when
//! this test was written: the test guards that the whole loop still does what it did.

use marvin::calibrate::{CalibrateConfig, calibrate};
use marvin::client::Client;
use marvin::protocol::WirePose;
use marvin::run::{RunConfig, Stop, run};
use marvin::server::{CellConfig, Server, ServerConfig};
use std::time::Duration;

fn server(seed: u64) -> (Server, Client) {
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml");
    let cell = CellConfig { world: world.into(), seed: Some(seed), cam_from_base: None, expose_truth: true };
    let server = Server::start(ServerConfig::new(cell, "127.0.0.1:0".parse().unwrap())).unwrap();
    let mut client = Client::connect(&server.addr().to_string(), Duration::from_secs(5)).unwrap();
    client.hello(None).unwrap();
    (server, client)
}

#[test]
fn the_table_is_cleared_from_what_the_cameras_see() {
    let library = mesh::Library::load_default().unwrap();
    let (s, mut c) = server(1);
    let calibration =
        calibrate(&mut c, &library, &CalibrateConfig::default(), &mut |_, _| Ok(()), &mut |_| {}).unwrap();
    let cam_from_base = calibration.solution.cam_from_base;
    s.stop();
    for seed in [5, 6] {
        let (s, mut c) = server(seed);
        c.set_hand_eye(WirePose::new(None, &cam_from_base)).unwrap();
        let on_table = c.truth().unwrap().objects.len();
        let report =
            run(&mut c, &library, &RunConfig::default(), &cam_from_base, &mut |_, _, _| Ok(()), &mut |_| Ok(()))
                .unwrap();
        let truth = c.truth().unwrap();
        let left: Vec<String> =
            truth.objects.iter().filter(|o| !o.in_bin).map(|o| format!("{} {}", o.id, o.model)).collect();
        eprintln!("seed {seed}: {} cycles, left on the table: {left:?}", report.cycles.len());
        assert_eq!(report.stop, Stop::NothingLocated, "seed {seed}");
        assert!(left.is_empty(), "seed {seed}: {} of {on_table} left on the table: {left:?}", left.len());
        s.stop();
    }
}
