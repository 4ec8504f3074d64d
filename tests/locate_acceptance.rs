//! The matcher's acceptance figures over 10 seeded scenes of the default world, as the matching
//! issue states them, measured by `marvin eval locate` against the scenes' ground truth.
//! (The README gives the same figures over 50 scenes and two held-out sets.)

use std::process::Command;

#[test]
fn ten_scenes_are_located_to_the_issues_figures() {
    let out = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["eval", "locate", "worlds/widgets.toml", "--scenes", "10", "--seed", "1", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let figure = |key: &str| doc[key].as_f64().unwrap_or_else(|| panic!("no `{key}` in {doc}"));
    assert_eq!(doc["scenes"], 10);
    assert!(figure("located_fraction") >= 0.95, "{doc}");
    assert!(figure("pos_err_mm_median") <= 2.0, "{doc}");
    assert!(figure("pos_err_mm_p90") <= 4.0, "{doc}");
    assert!(figure("rot_err_deg_median") <= 1.0, "{doc}");
    assert!(figure("false_positive_fraction") <= 0.01, "{doc}");
}
