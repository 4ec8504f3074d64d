//! A run recorded for rerun: `marvin run --rerun FILE.rrd` writes a file that rerun's own reader
//! decodes to the end, holding the entities a person looks for (the cameras and their images,
//! the edgels and 2D lines, the 3D lines, the located parts, the calibration, the bins, the
//! objects, stage times, the log).
#![cfg(feature = "rerun")]

use re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};
use std::collections::BTreeSet;
use std::process::Command;

#[test]
fn a_run_is_recorded_with_its_entities() {
    let dir = std::env::temp_dir().join(format!("marvin-rrd-{}", std::process::id()));
    let path = dir.join("run.rrd");
    let world = concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .args(["run", world, "--max-cycles", "2", "--rerun", path.to_str().unwrap()])
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
    assert!(messages > 10, "only {messages} messages");
    for wanted in [
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
    ] {
        assert!(entities.contains(wanted), "no `{wanted}` in the recording; it holds {entities:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
