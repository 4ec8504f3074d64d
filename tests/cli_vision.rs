//! End to end: `marvin edges` and `marvin stereo` on rendered images, and their errors.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn marvin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_marvin")).current_dir(env!("CARGO_MANIFEST_DIR")).args(args).output().unwrap()
}

/// A rendered default scene, made once per test binary run.
fn rendered() -> PathBuf {
    static ONCE: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    ONCE.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_vision_scene");
        let out = marvin(&["render", "worlds/widgets.toml", "--seed", "3", "--out", dir.to_str().unwrap()]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        dir
    })
    .clone()
}

fn path(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn edges_json_lists_edgels_and_strings() {
    let left = rendered().join("left.png");
    let out = marvin(&["edges", path(&left), "--json"]);
    assert!(out.status.success());
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let edgels = doc["edgels"].as_array().unwrap();
    assert!(edgels.len() > 1000);
    for key in ["x", "y", "orientation", "contrast"] {
        assert!(edgels[0][key].is_number(), "edgel lacks {key}");
    }
    let strings = doc["strings"].as_array().unwrap();
    assert!(!strings.is_empty());
    assert!(strings.iter().all(|s| s.as_array().unwrap().len() >= 5));
}

#[test]
fn stereo_json_lists_matches_with_disparities_in_range() {
    let dir = rendered();
    let out = marvin(&[
        "stereo",
        "--left",
        path(&dir.join("left.png")),
        "--right",
        path(&dir.join("right.png")),
        "--calib",
        path(&dir.join("scene.json")),
        "--json",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let matches = doc["matches"].as_array().unwrap();
    assert!(matches.len() > 500, "{} matches", matches.len());
    // 0.2 m baseline, f = 1000 px, the workspace 0.6-1.6 m away.
    assert!(matches.iter().all(|m| (125.0..=334.0).contains(&m["disparity"].as_f64().unwrap())));
}

#[test]
fn stereo_refuses_bad_input_and_says_which() {
    let dir = rendered();
    let (left, right, calib) = (dir.join("left.png"), dir.join("right.png"), dir.join("scene.json"));
    let small = dir.join("small.png");
    image::GrayImage::new(100, 80).save(&small).unwrap();
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec!["--left", path(&left), "--right", path(&small), "--calib", path(&calib)],
            format!("{} is 100x80", path(&small)),
        ),
        (vec!["--left", path(&left), "--right", "/no/such.png", "--calib", path(&calib)], "/no/such.png".into()),
        (vec!["--left", path(&left), "--right", path(&right), "--calib", path(&left)], path(&left).to_string()),
        (vec!["--left", path(&left), "--right", path(&right)], "--calib".into()),
    ];
    for (args, expected) in cases {
        let mut all = vec!["stereo"];
        all.extend(args);
        let out = marvin(&all);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{all:?} should fail");
        assert!(stderr.contains(&expected), "{all:?}: stderr {stderr} should mention {expected}");
    }
}

#[test]
fn locate_reports_poses_grasps_and_misses() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_locate");
    let out = marvin(&["locate", "worlds/widgets.toml", "--seed", "1", "--json", "--out", path(&dir)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let located = doc["located"].as_array().unwrap();
    assert!(located.iter().any(|l| l["correct"] == true), "nothing located correctly: {doc}");
    let xyz =
        |v: &serde_json::Value| -> Vec<f64> { v.as_array().unwrap().iter().map(|c| c.as_f64().unwrap()).collect() };
    for l in located {
        let at = xyz(&l["cam_from_model"]["translation_m"]);
        assert!(l["grasp_cam_from_gripper"]["rotation_xyzw"].is_array());
        // The 3D lines it rests on: at least the three a report needs, each near the object.
        let lines = l["scene_lines"].as_array().unwrap();
        assert!(lines.len() >= 3, "{l}");
        for end in lines.iter().flat_map(|s| [&s["a_m"], &s["b_m"]]) {
            let d = xyz(end).iter().zip(&at).map(|(p, q)| (p - q).powi(2)).sum::<f64>().sqrt();
            assert!(d < 0.1, "a line end {d:.3} m from its object: {l}");
        }
    }
    assert!(doc["missed"].is_array());
    assert!(dir.join("located.png").exists());
    let bad = marvin(&["locate", "worlds/widgets.toml", "--models", "teapot"]);
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("teapot"));
}

/// Seed 6 hides most of its L-bracket behind other parts; `locate` reports it missed, with the
/// fraction of its edges in view and the evidence its true pose finds.
#[test]
fn locate_says_how_much_of_a_missed_object_was_visible() {
    let out = marvin(&["locate", "worlds/widgets.toml", "--seed", "6", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let missed = doc["missed"].as_array().unwrap();
    let bracket = missed.iter().find(|m| m["model"] == "l_bracket").unwrap_or_else(|| panic!("{doc}"));
    let visible = bracket["visible_fraction"].as_f64().unwrap();
    assert!((0.1..0.3).contains(&visible), "{visible}");
    for key in ["support_fraction_at_truth", "image_support_at_truth"] {
        assert!((0.0..=1.0).contains(&bracket[key].as_f64().unwrap()), "{key}: {bracket}");
    }
    assert!(bracket["supported_lines_at_truth"].is_u64());
}
