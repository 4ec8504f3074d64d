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
    every_part_in_scene_obj_covers_its_pixels(&out, &scene);
}

/// scene.obj holds each part where the renderer drew it: every left pixel the id map gives to
/// `object_<id>` lies within the box its OBJ vertices project to through the true left camera,
/// and its depth within theirs.
fn every_part_in_scene_obj_covers_its_pixels(out: &std::path::Path, scene: &serde_json::Value) {
    let text = std::fs::read_to_string(out.join("scene.obj")).unwrap();
    let mut vertices: Vec<nalgebra::Point3<f64>> = Vec::new();
    let mut groups: Vec<(String, Vec<usize>)> = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("o") => groups.push((words.next().unwrap().to_string(), Vec::new())),
            Some("v") => {
                let c: Vec<f64> = words.map(|w| w.parse().unwrap()).collect();
                groups.last_mut().unwrap().1.push(vertices.len());
                vertices.push(nalgebra::Point3::new(c[0], c[1], c[2]));
            }
            _ => {}
        }
    }
    let rig: sim::realism::RigAsBuilt = serde_json::from_value(scene["as_built"].clone()).unwrap();
    let cam = rig.left.lens_camera();
    let cam_from_world = cam.pinhole.cam_from_world();
    let ids = image::open(out.join("ids_left.png")).unwrap().into_luma16();
    let depth = image::open(out.join("depth_left.png")).unwrap().into_luma16();
    for o in scene["objects"].as_array().unwrap() {
        let id = o["id"].as_u64().unwrap() as u16;
        let name = format!("object_{id}_{}", o["model"].as_str().unwrap());
        let (_, own) = groups.iter().find(|(n, _)| *n == name).unwrap_or_else(|| panic!("no {name} in scene.obj"));
        let in_cam: Vec<nalgebra::Point3<f64>> = own.iter().map(|&i| cam_from_world * vertices[i]).collect();
        let px: Vec<nalgebra::Point2<f64>> = in_cam.iter().map(|p| cam.project_cam(p).unwrap()).collect();
        let (x0, x1) =
            (px.iter().map(|p| p.x).fold(f64::MAX, f64::min), px.iter().map(|p| p.x).fold(f64::MIN, f64::max));
        let (y0, y1) =
            (px.iter().map(|p| p.y).fold(f64::MAX, f64::min), px.iter().map(|p| p.y).fold(f64::MIN, f64::max));
        let (z0, z1) =
            (in_cam.iter().map(|p| p.z).fold(f64::MAX, f64::min), in_cam.iter().map(|p| p.z).fold(f64::MIN, f64::max));
        let mut seen = 0;
        for (x, y, p) in ids.enumerate_pixels().filter(|(_, _, p)| p.0[0] == id) {
            let (x, y) = (f64::from(x), f64::from(y));
            assert!(x >= x0 - 1.0 && x <= x1 + 1.0 && y >= y0 - 1.0 && y <= y1 + 1.0, "{name}: pixel ({x}, {y}) {p:?}");
            let z = f64::from(depth.get_pixel(x as u32, y as u32).0[0]) * 1e-4;
            assert!(z >= z0 - 0.001 && z <= z1 + 0.001, "{name}: depth {z} outside {z0}-{z1}");
            seen += 1;
        }
        assert!(seen > 0, "{name} not seen by the left camera");
    }
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
