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
