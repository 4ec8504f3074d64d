//! A run recorded for rerun: `marvin run --rerun FILE.rrd` writes a file that rerun's own reader
//! decodes to the end, holding the entities a person looks for (the cameras and their images,
//! the edgels and 2D lines, the 3D lines, the located parts, the calibration, the bins, the
//! objects, stage times, the log). `marvin locate --rerun`, `marvin calibrate --rerun` and
//! `marvin pick --rerun` record what they have.
//!
//! On the ideal copy of the world (`worlds/ideal/`): in the realistic cell the hand-eye
//! calibration that `run` and `calibrate` start with finds no flag yet (README, "The realistic
//! cell"), and these tests are about what a recording holds.
#![cfg(feature = "rerun")]

use re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};
use std::collections::BTreeSet;
use std::process::Command;

/// Runs `marvin` with `args` (the recording's path last) and returns the entities the
/// recording it writes holds, decoded with rerun's own reader to the end.
fn recorded_entities(name: &str, args: &[&str]) -> BTreeSet<String> {
    let dir = std::env::temp_dir().join(format!("marvin-rrd-{}-{name}", std::process::id()));
    let path = dir.join(format!("{name}.rrd"));
    let out = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let file = std::io::BufReader::new(std::fs::File::open(&path).unwrap());
    let mut entities = BTreeSet::new();
    let mut messages = 0;
    for msg in DecoderApp::decode_eager(file).expect("an rrd file") {
        messages += 1;
        if let LogMsg::ArrowMsg(_, arrow) = msg.expect("every message decodes") {
            let chunk = Chunk::from_arrow_msg(&arrow).expect("a chunk");
            entities.insert(chunk.entity_path().to_string().trim_start_matches('/').to_string());
        }
    }
    assert!(messages > 5, "only {messages} messages");
    let _ = std::fs::remove_dir_all(&dir);
    entities
}

fn assert_holds(entities: &BTreeSet<String>, wanted: &[&str]) {
    for w in wanted {
        assert!(entities.contains(*w), "no `{w}` in the recording; it holds {entities:?}");
    }
}

#[test]
fn a_run_is_recorded_with_its_entities() {
    let entities = recorded_entities("run", &["run", "worlds/ideal/widgets.toml", "--max-cycles", "2", "--rerun"]);
    assert_holds(
        &entities,
        &[
            "cell/camera/left",
            "cell/camera/left/image",
            "cell/camera/left/image/edgels",
            "cell/camera/left/image/lines2d",
            "cell/camera/right/image",
            "cell/lines3d",
            "cell/located/0",
            "cell/located/0/grasp",
            "cell/calibration/sightings/seen",
            "cell/calibration/solved_camera",
            "cell/calibration/true_camera",
            "cell/bins",
            "cell/path",
            "cell/arm/upper_arm",
            "cell/fixed/table",
            "cell/truth/objects/1",
            "stages/match",
            "joints/shoulder",
            "log",
        ],
    );
}

#[test]
fn locate_calibrate_and_pick_record_what_they_have() {
    let picked = recorded_entities("pick", &["pick", "worlds/ideal/widgets.toml", "--object", "1", "--rerun"]);
    assert_holds(
        &picked,
        &["cell/fixed/table", "cell/truth/objects/1", "cell/truth/objects/7", "cell/arm/upper_arm", "log"],
    );
    let located = recorded_entities("locate", &["locate", "worlds/ideal/widgets.toml", "--seed", "2", "--rerun"]);
    assert_holds(
        &located,
        &[
            "cell/camera/left",
            "cell/camera/left/image",
            "cell/camera/left/image/edgels",
            "cell/camera/right/image",
            "cell/lines3d",
            "cell/located/0",
            "cell/located/0/grasp",
            "cell/fixed/table",
            "log",
        ],
    );
    let calibrated = recorded_entities(
        "calibrate",
        &["calibrate", "worlds/ideal/widgets.toml", "--poses", "8", "--out", "target/tmp/rrd_hand_eye.json", "--rerun"],
    );
    assert_holds(
        &calibrated,
        &[
            "cell/calibration/sightings/seen",
            "cell/calibration/sightings/robot",
            "cell/calibration/solved_camera",
            "cell/calibration/true_camera",
            "cell/fixed/table",
            "log",
        ],
    );
}

/// `marvin calibrate cameras --rerun`: each view's images with the corners found, their
/// reprojections and residuals, the cameras and the boards. On the realistic world: the camera
/// calibration works there.
#[test]
fn a_camera_calibration_is_recorded_view_by_view() {
    let entities = recorded_entities(
        "cameras",
        &["calibrate", "cameras", "worlds/widgets.toml", "--seed", "3", "--out", "target/rrd-cameras", "--rerun"],
    );
    assert_holds(
        &entities,
        &[
            "rig/camera/left",
            "rig/camera/right/image",
            "rig/camera/left/image/corners/found",
            "rig/camera/left/image/corners/reprojected",
            "rig/camera/right/image/corners/residual_x100",
            "rig/boards",
            "log",
        ],
    );
}
