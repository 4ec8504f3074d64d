//! End to end: `marvin render` on the default world writes what its help promises, and a
//! malformed world file is refused with its file, line and field.

use std::path::{Path, PathBuf};
use std::process::Command;

fn marvin() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_marvin"));
    cmd.current_dir(env!("CARGO_MANIFEST_DIR"));
    cmd
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn render_writes_images_maps_and_scene_json() {
    let out = scratch("render_default");
    let status = marvin().args(["render", "worlds/widgets.toml", "--seed", "4", "--out"]).arg(&out).status().unwrap();
    assert!(status.success());
    for side in ["left", "right"] {
        let grey = image::open(out.join(format!("{side}.png"))).unwrap();
        assert_eq!((grey.width(), grey.height()), (512, 512));
        assert!(matches!(grey, image::DynamicImage::ImageLuma8(_)));
        let depth = image::open(out.join(format!("depth_{side}.png"))).unwrap().into_luma16();
        let ids = image::open(out.join(format!("ids_{side}.png"))).unwrap().into_luma16();
        // The table fills the view: every pixel has a depth, 0.5-2 m away (units of 0.1 mm).
        assert!(depth.pixels().all(|p| (5_000..20_000).contains(&p.0[0])));
        let seen: std::collections::BTreeSet<u16> = ids.pixels().map(|p| p.0[0]).collect();
        assert!(seen.len() >= 6, "{side}: ids seen {seen:?}");
    }
    let scene: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("scene.json")).unwrap()).unwrap();
    assert_eq!(scene["seed"], 4);
    assert_eq!(scene["objects"].as_array().unwrap().len(), 7);
    let calib = mesh::StereoCalibration::load(&out.join("scene.json")).unwrap();
    assert!((calib.baseline() - 0.2).abs() < 1e-9);
}

#[test]
fn a_malformed_world_is_refused_with_file_line_and_field() {
    let dir = scratch("malformed");
    std::fs::create_dir_all(&dir).unwrap();
    let good = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("worlds/widgets.toml")).unwrap();
    let bad = good.replacen("focal_px = 1000.0", "focal_px = \"long\"", 1);
    let line = bad.lines().position(|l| l.contains("\"long\"")).unwrap() + 1;
    let path = dir.join("bad.toml");
    std::fs::write(&path, bad).unwrap();
    let output = marvin().arg("render").arg(&path).arg("--out").arg(dir.join("out")).output().unwrap();
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains(&format!("bad.toml:{line}: field `cameras.left.focal_px`")), "stderr was: {stderr}");
    assert!(!dir.join("out").exists(), "nothing should be written for a bad world");
}
