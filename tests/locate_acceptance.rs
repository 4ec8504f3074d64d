//! The matcher over 10 seeded scenes, 360001-360010 (never used to choose a parameter, see the
//! README's "Seeds"), measured by `marvin eval locate` against the scenes' ground truth, with the
//! table placed by a hand-eye calibration as `marvin run` places it.
//!
//! The test ran on 10001-10010 until that range had served for choices. The limits sit near what
//! the matcher measured on those scenes when they were first run
//! (located 0.957 = 67 of 70, false reports 0.043 = 3 of 70, position error median 0.19 mm and
//! p90 0.69 mm, rotation median 0.28 deg), with a margin of one object either way for the
//! fractions and about half again for the errors: a change that loses an object, adds a false
//! report or blurs the poses fails here. On these scenes the matching issue's false-report target
//! (0.01) is not met; the vision issue (17) is to bring it down, and this test's limits with it.
//!
//! Run on the ideal copy of the world (`worlds/ideal/`): these figures were measured in the ideal
//! cell and vision has not yet earned them in the realistic one (README, "The realistic cell").

use std::process::Command;

#[test]
fn ten_reporting_scenes_are_located_as_measured() {
    let out = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["eval", "locate", "worlds/ideal/widgets.toml", "--scenes", "10", "--seed", "360001", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let figure = |key: &str| doc[key].as_f64().unwrap_or_else(|| panic!("no `{key}` in {doc}"));
    assert_eq!(doc["scenes"], 10);
    assert_eq!(doc["unsettled_scenes"], 0, "{doc}");
    // One object of the 70 fewer than measured (66 of 70 = 0.943) still passes.
    assert!(figure("located_fraction") >= 0.94, "{doc}");
    // One false report more than measured (4 of 70 = 0.057) still passes.
    assert!(figure("false_positive_fraction") <= 0.06, "{doc}");
    assert!(figure("pos_err_mm_median") <= 0.3, "{doc}");
    assert!(figure("pos_err_mm_p90") <= 1.0, "{doc}");
    assert!(figure("rot_err_deg_median") <= 0.45, "{doc}");
}
