//! Bad numbers on the command line and incoherent calibrations are refused with an error that
//! names the value, before any work is done.

use mesh::{PinholeCamera, StereoCalibration};
use nalgebra::{Point3, Vector3};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn marvin(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_marvin")).current_dir(env!("CARGO_MANIFEST_DIR")).args(args).output().unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A 64x64 grey image with a bright square: something to find edges in.
fn image(dir: &Path) -> PathBuf {
    let img = image::GrayImage::from_fn(64, 64, |x, y| {
        image::Luma([if (16..48).contains(&x) && (16..48).contains(&y) { 200 } else { 40 }])
    });
    let path = dir.join("square.png");
    img.save(&path).unwrap();
    path
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn a_sigma_that_is_no_gaussian_is_refused_naming_it() {
    let img = image(&scratch("inputs_sigma"));
    let img = img.to_str().unwrap();
    for bad in ["0", "nan", "-1", "1000", "inf"] {
        let o = marvin(&["edges", img, "--sigma", bad]);
        assert!(!o.status.success(), "--sigma {bad} was accepted");
        let e = stderr(&o);
        assert!(e.contains("--sigma") && (e.contains(bad) || e.contains("NaN")), "--sigma {bad}: {e}");
    }
    assert!(marvin(&["edges", img, "--sigma", "1.5"]).status.success());
}

#[test]
fn a_calibration_without_a_baseline_or_with_mismatched_cameras_is_refused() {
    let dir = scratch("inputs_calib");
    let img = image(&dir);
    let img = img.to_str().unwrap();
    let cam = |x: f64, size: u32| {
        PinholeCamera::looking_at(
            (size, size),
            100.0,
            [31.5, 31.5],
            Point3::new(x, -0.7, 0.6),
            Point3::origin(),
            Vector3::z(),
        )
    };
    for (name, calib, want) in [
        ("same.json", StereoCalibration { left: cam(0.0, 64), right: cam(0.0, 64) }, "apart"),
        ("sizes.json", StereoCalibration { left: cam(-0.1, 64), right: cam(0.1, 128) }, "128x128"),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, serde_json::to_string(&calib).unwrap()).unwrap();
        let o = marvin(&["stereo", "--left", img, "--right", img, "--calib", path.to_str().unwrap()]);
        assert!(!o.status.success(), "{name} was accepted");
        let e = stderr(&o);
        assert!(e.contains(name) && e.contains(want), "{name}: {e}");
    }
}

/// Every count, seed, slice number and duration on the command line is checked by clap before
/// anything runs; the error names the flag and the value.
#[test]
fn numbers_out_of_range_on_the_command_line_are_refused_naming_them() {
    let world = "worlds/widgets.toml";
    let cases: [(&[&str], &str, &str); 9] = [
        (&["eval", "locate", world, "--scenes", "0"], "--scenes", "0"),
        (&["eval", "pick", world, "--trials", "0"], "--trials", "0"),
        (&["eval", "vision", world, "--scenes", "1", "--slices", "0"], "--slices", "0"),
        (&["eval", "vision", world, "--seed", "18446744073709551615"], "--seed", "18446744073709551615"),
        (&["eval", "calibrate", world, "--poses", "2"], "--poses", "2"),
        (&["bench", "vision", "--runs", "0"], "--runs", "0"),
        (&["serve", world, "--idle-timeout-s", "nan"], "--idle-timeout-s", "NaN"),
        (&["serve", world, "--idle-timeout-s", "-3"], "--idle-timeout-s", "-3"),
        (&["run", world, "--max-cycles", "0"], "--max-cycles", "0"),
    ];
    for (args, flag, value) in cases {
        let o = marvin(args);
        assert!(!o.status.success(), "{args:?} was accepted");
        let e = stderr(&o);
        assert!(e.contains(flag) && e.contains(value), "{args:?}: {e}");
    }
}

#[test]
fn a_disparity_range_that_is_none_is_refused() {
    let img = image(&scratch("inputs_disparity"));
    let img = img.to_str().unwrap();
    for bad in ["0:inf", "nan:10", "5:5", "-1e9:10"] {
        let o = marvin(&["stereo", "--left", img, "--right", img, "--rectified", "--disparity", bad]);
        assert!(!o.status.success(), "--disparity {bad} was accepted");
        let e = stderr(&o);
        assert!(e.contains("--disparity") && e.contains(bad), "--disparity {bad}: {e}");
    }
}

/// A calibration file whose camera could not project (a focal length that is no length, a
/// principal point off the image, a rotation that is not one) is refused naming the field.
#[test]
fn an_incoherent_camera_in_a_calibration_is_refused_naming_the_field() {
    let dir = scratch("inputs_camera");
    let img = image(&dir);
    let img = img.to_str().unwrap();
    let good = StereoCalibration {
        left: PinholeCamera::looking_at(
            (64, 64),
            100.0,
            [31.5, 31.5],
            Point3::new(-0.1, -0.7, 0.6),
            Point3::origin(),
            Vector3::z(),
        ),
        right: PinholeCamera::looking_at(
            (64, 64),
            100.0,
            [31.5, 31.5],
            Point3::new(0.1, -0.7, 0.6),
            Point3::origin(),
            Vector3::z(),
        ),
    };
    let text = serde_json::to_string(&good).unwrap();
    let mut negative = good.clone();
    negative.left.fx = -100.0;
    let mut off_image = good.clone();
    off_image.right.cy = 500.0;
    let mut doc: serde_json::Value = serde_json::from_str(&text).unwrap();
    doc["right"]["world_from_cam"]["rotation_xyzw"] = serde_json::json!([0.0, 0.0, 0.0, 1.5]);
    for (name, body, want) in [
        ("negative.json", serde_json::to_string(&negative).unwrap(), "left.fx"),
        ("off_image.json", serde_json::to_string(&off_image).unwrap(), "right.cy"),
        ("stretched.json", doc.to_string(), "unit quaternion"),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, body).unwrap();
        let o = marvin(&["stereo", "--left", img, "--right", img, "--calib", path.to_str().unwrap()]);
        assert!(!o.status.success(), "{name} was accepted");
        let e = stderr(&o);
        assert!(e.contains(name) && e.contains(want), "{name}: {e}");
    }
    let path = dir.join("good.json");
    std::fs::write(&path, text).unwrap();
    assert!(marvin(&["stereo", "--left", img, "--right", img, "--calib", path.to_str().unwrap()]).status.success());
}

/// A world whose clutter asks for no objects, or holds a number that is none, is refused by
/// every verb that reads it, naming file, line and field.
#[test]
fn a_world_with_an_empty_clutter_entry_or_a_nan_is_refused() {
    let dir = scratch("inputs_world");
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("worlds/widgets.toml")).unwrap();
    for (name, from, to, field) in [
        ("zero.toml", "{ model = \"wedge\" }", "{ model = \"wedge\", count = 0 }", "clutter.objects[4].count"),
        (
            "nan.toml",
            "focal_px = 1000.0\nposition_m = [0.1",
            "focal_px = nan\nposition_m = [0.1",
            "cameras.right.focal_px",
        ),
    ] {
        assert!(text.contains(from), "{from}");
        let bad = text.replacen(from, to, 1);
        let line = bad.lines().position(|l| l.contains(to.lines().next().unwrap())).unwrap() + 1;
        let path = dir.join(name);
        std::fs::write(&path, &bad).unwrap();
        for verb in ["render", "locate"] {
            let o = marvin(&[verb, path.to_str().unwrap()]);
            assert!(!o.status.success(), "{verb} {name} was accepted");
            let e = stderr(&o);
            assert!(e.contains(&format!("{name}:{line}")) && e.contains(field), "{verb} {name}: {e}");
        }
    }
}

/// A scene that never came to rest is said to be one: a warning from `render`, a count from
/// `eval` (here the settling time is cut to 10 ms, so the dropped parts are still falling). On
/// the ideal world: `eval locate` calibrates the hand-eye transform to place the table, which
/// through the world file's cameras sees the flag only in the ideal cell.
#[test]
fn an_unsettled_scene_is_reported() {
    let dir = scratch("inputs_unsettled");
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("worlds/ideal/widgets.toml")).unwrap();
    let world = dir.join("falling.toml");
    std::fs::write(
        &world,
        text.replace("[render]", "[physics]\ntimestep_s = 0.004\nsettle_limit_s = 0.01\nfriction = 0.7\n\n[render]")
            .replace("../../urdf/", concat!(env!("CARGO_MANIFEST_DIR"), "/urdf/")),
    )
    .unwrap();
    let world = world.to_str().unwrap();
    let o = marvin(&["render", world, "--out", dir.join("render").to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("warning: an unsettled scene") && stderr(&o).contains("not at rest"), "{}", stderr(&o));
    let o = marvin(&["eval", "locate", world, "--scenes", "2", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(doc["unsettled_scenes"], 2, "{doc}");
    // The shipped world settles.
    let o = marvin(&["eval", "locate", "worlds/ideal/widgets.toml", "--scenes", "1", "--json"]);
    let doc: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(doc["unsettled_scenes"], 0, "{doc}");
    assert!(doc["table"].as_str().is_some_and(|t| t.starts_with("hand-eye calibration")), "{doc}");
}

/// A camera calibration file that is missing, or lacks a field, is refused before any server
/// starts, naming the file (and the field).
#[test]
fn a_bad_camera_calibration_file_is_refused_naming_it() {
    let dir = scratch("inputs_cameras");
    let bad = dir.join("cameras.json");
    std::fs::write(&bad, r#"{"format": "marvin-cameras/1", "width": 512}"#).unwrap();
    let bad = bad.to_str().unwrap();
    for args in [
        vec!["run", "worlds/ideal/widgets.toml", "--cameras", bad],
        vec!["calibrate", "worlds/ideal/widgets.toml", "--cameras", bad],
        vec!["run", "worlds/ideal/widgets.toml", "--cameras", "/no/such/cameras.json"],
    ] {
        let o = marvin(&args);
        assert!(!o.status.success(), "{args:?} was accepted");
        let e = stderr(&o);
        assert!(e.contains(args[3]), "{args:?}: {e}");
    }
    let e = stderr(&marvin(&["run", "worlds/ideal/widgets.toml", "--cameras", bad]));
    assert!(e.contains("height") || e.contains("left"), "the missing field is not named: {e}");
    for verb in ["vision", "locate"] {
        let o = marvin(&["eval", verb, "worlds/ideal/widgets.toml", "--scenes", "1", "--cameras", bad]);
        assert!(!o.status.success() && stderr(&o).contains(bad), "eval {verb}: {}", stderr(&o));
    }
}
