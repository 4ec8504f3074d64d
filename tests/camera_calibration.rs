//! Camera calibration on the realistic cell's own renders: the board placed at tilted poses in
//! front of the rig (directly in the scene: the arm cannot yet carry it, see issue 51's note),
//! rendered through the true lenses and sensors, its corners found, both cameras and the rig
//! solved, and the result compared with the cameras as built.

use camera_calib::detect::detect;
use camera_calib::{Board, Intrinsics, Options, ViewCorners, calibrate_stereo};
use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use std::path::Path;

/// World poses of the board model: centres over the table, faces turned to the rig and tilted
/// 15-40 deg in every direction.
fn board_poses(n: usize, seed: u64, towards: Point3<f64>, half: Vector3<f64>) -> Vec<Isometry3<f64>> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut out = Vec::new();
    while out.len() < n {
        let centre =
            Point3::new(rng.random_range(-0.13..0.13), rng.random_range(-0.12..0.10), rng.random_range(0.06..0.2));
        let to_rig = (towards - centre).normalize();
        let across = Unit::new_normalize(to_rig.cross(&Vector3::z()));
        let up = across.cross(&to_rig);
        let a = rng.random_range(0.0..std::f64::consts::TAU);
        let axis = Unit::new_normalize(across.as_ref() * a.cos() + up * a.sin());
        let normal = UnitQuaternion::from_axis_angle(&axis, rng.random_range(15.0f64..40.0).to_radians()) * to_rig;
        let down = (-Vector3::z() - normal * (-Vector3::z()).dot(&normal)).normalize();
        let x = UnitQuaternion::from_axis_angle(&Unit::new_normalize(normal), rng.random_range(-0.5..0.5)) * down;
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, normal.cross(&x), normal]));
        let pose = Isometry3::from_parts(Translation3::from(centre.coords), UnitQuaternion::from_rotation_matrix(&r));
        let lowest = [-1.0, 1.0]
            .iter()
            .flat_map(|&s| [-1.0, 1.0].map(|t| (pose * Point3::new(s * half.x, t * half.y, 0.0)).z))
            .fold(f64::MAX, f64::min);
        if lowest > 0.01 {
            out.push(pose);
        }
    }
    out
}

fn intrinsics(c: &sim::realism::CameraAsBuilt) -> Intrinsics {
    Intrinsics { fx: c.pinhole.fx, fy: c.pinhole.fy, cx: c.pinhole.cx, cy: c.pinhole.cy, distortion: c.lens.distortion }
}

/// Renders the views of `poses` and finds the board in each image.
fn views(world: &sim::world::WorldFile, poses: &[Isometry3<f64>]) -> Vec<ViewCorners> {
    let library = mesh::Library::load_default().unwrap();
    let board = library.get("board").unwrap();
    let im = sim::imaging::Imaging::new(world);
    poses
        .iter()
        .enumerate()
        .map(|(k, pose)| {
            let statics = sim::scene::static_boxes(world).into_iter().map(|b| (0, b.mesh(), im.static_finish(&b)));
            let item = (9u32, board.mesh.transformed(pose), im.object_finish(board, 9, 0));
            let scene = im.scene(statics.chain(std::iter::once(item)));
            let (l, r) = im.render_stereo(&scene, 1000 + k as u64);
            let grey = |f: &sim::render::Frame| {
                image::GrayImage::from_raw(f.width as u32, f.height as u32, f.image.clone()).unwrap()
            };
            ViewCorners {
                left: detect(&grey(&l), &Board::LIBRARY).ok(),
                right: detect(&grey(&r), &Board::LIBRARY).ok(),
            }
        })
        .collect()
}

#[test]
fn the_realistic_rig_is_calibrated_from_its_own_renders() {
    let world =
        sim::world::WorldFile::load(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml"))).unwrap();
    let im = sim::imaging::Imaging::new(&world);
    let rig = &im.rig;
    let towards = nalgebra::center(&rig.left.pinhole.centre(), &rig.right.pinhole.centre());
    let library = mesh::Library::load_default().unwrap();
    let half = library.get("board").unwrap().extent() / 2.0;
    // Tuning seed 7 (seeds 1-9999 are for tuning).
    let v = views(&world, &board_poses(20, 7, towards, half));
    let both = v.iter().filter(|v| v.left.is_some() && v.right.is_some()).count();
    let s = calibrate_stereo(&Board::LIBRARY, [512, 512], &v, &Options::default()).unwrap();
    let (left, right) = (intrinsics(&rig.left), intrinsics(&rig.right));
    let right_from_left = rig.right.pinhole.cam_from_world() * rig.left.pinhole.world_from_cam;
    let centre = |p: &Isometry3<f64>| p.inverse().translation.vector;
    println!("views with the board in both images: {both} of {}", v.len());
    println!("rms {:.4} px (left {:.4}, right {:.4})", s.rms_px, s.left_rms_px, s.right_rms_px);
    for (name, got, want, sd) in [("left", s.left, left, s.left_sigma), ("right", s.right, right, s.right_sigma)] {
        println!(
            "{name}: fx {:+.4}% fy {:+.4}% cx {:+.3} cy {:+.3} px; sigmas fx {:.4}% cx {:.3} px; k1 {:.4} vs {:.4}",
            100.0 * (got.fx - want.fx) / want.fx,
            100.0 * (got.fy - want.fy) / want.fy,
            got.cx - want.cx,
            got.cy - want.cy,
            100.0 * sd[0] / want.fx,
            sd[2],
            got.distortion.k1,
            want.distortion.k1
        );
    }
    let (a, b) = (centre(&s.right_from_left), centre(&right_from_left));
    let baseline_mm = (a.norm() - b.norm()) * 1e3;
    let position_mm = (a - b).norm() * 1e3;
    let rotation_deg = s.right_from_left.rotation.angle_to(&right_from_left.rotation).to_degrees();
    println!("baseline {baseline_mm:+.4} mm, position {position_mm:.4} mm, rotation {rotation_deg:.4} deg");
    assert!(both >= 8, "the board was found in both images in {both} of 20 views");
    assert!(s.rms_px < 0.08, "reprojection RMS {} px", s.rms_px);
    for (name, got, want, sd) in [("left", s.left, left, s.left_sigma), ("right", s.right, right, s.right_sigma)] {
        // Each against the truth: within 3.5 reported sigmas, and within bounds a few times
        // OpenCV's median errors on this geometry (issue 51: fx 0.03-0.04%, cx 0.75-0.9 px,
        // distortion 0.23 px).
        let (g, w) = (got.to_params(), want.to_params());
        for k in 0..4 {
            let err = (g[k] - w[k]).abs();
            assert!(
                err <= 3.5 * sd[k],
                "{name} {}: off by {err:.4}, reported sigma {:.4}",
                camera_calib::camera::INTRINSIC_NAMES[k],
                sd[k]
            );
        }
        assert!(
            ((got.fx - want.fx) / want.fx).abs() < 0.0015 && ((got.fy - want.fy) / want.fy).abs() < 0.0015,
            "{name}: {got:?}"
        );
        assert!((got.cx - want.cx).abs() < 2.0 && (got.cy - want.cy).abs() < 2.0, "{name}: {got:?}");
        let field = camera_calib::camera::distortion_difference_px(&got, &want, [512, 512]);
        println!("{name}: distortion field {field:.3} px at worst");
        assert!(field < 0.6, "{name}: the distortion field is {field:.3} px off at worst");
    }
    assert!(baseline_mm.abs() < 0.2 && position_mm < 0.6 && rotation_deg < 0.15, "the rig is off");
}

/// `marvin calibrate cameras` end to end: the arm carries the board through the realistic
/// cell, the files are written, and the solution (computed without the truth) is compared with
/// the cameras as built by the command itself, after the solve. Seed 11: never used for a
/// choice.
#[test]
fn calibrate_cameras_through_the_arm_finds_the_cameras_as_built() {
    let out = std::env::temp_dir().join(format!("marvin_calibrate_cameras_{}", std::process::id()));
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_marvin"))
        .args([
            "calibrate",
            "cameras",
            concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/widgets.toml"),
            "--seed",
            "11",
            "--json",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let used = doc["views"].as_array().unwrap().iter().filter(|v| !v["left_rms_px"].is_null()).count();
    assert!(used >= 10, "{used} views used");
    assert!(doc["rms_px"].as_f64().unwrap() < 0.08, "{}", doc["rms_px"]);
    let e = &doc["error"];
    println!("{e}");
    for side in ["left", "right"] {
        let c = &e[side];
        let f = |k: &str| c[k].as_f64().unwrap().abs();
        assert!(f("fx_rel") < 0.0015 && f("fy_rel") < 0.0015, "{side}: {c}");
        assert!(f("cx_px") < 2.0 && f("cy_px") < 2.0, "{side}: {c}");
        assert!(f("distortion_px_max") < 0.6, "{side}: {c}");
    }
    let g = |k: &str| e[k].as_f64().unwrap().abs();
    assert!(g("baseline_mm") < 0.2 && g("right_position_mm") < 0.6 && g("rotation_deg") < 0.15, "{e}");
    let file = camera_calib::file::CamerasFile::load(&out.join("cameras.json")).unwrap();
    assert_eq!((file.width, file.height), (512, 512));
    for name in ["left.yaml", "right.yaml"] {
        let yaml = std::fs::read_to_string(out.join(name)).unwrap();
        assert!(yaml.contains("distortion_model: plumb_bob") && yaml.contains("projection_matrix:"), "{yaml}");
    }
    std::fs::remove_dir_all(&out).unwrap();
}

/// Where the planned poses do not determine the cameras, `marvin calibrate cameras` visits
/// more, as an operator would take more pictures. Ideal `widgets.toml` tuning seed 8: of its 24
/// planned poses only 4 showed the whole board in both images (the board cut off by an
/// image's edge, or a corner behind the jaws), and the calibration failed for want of corners
/// near the image's edges; with the poses after them it solves, and the solution (computed
/// without the truth) matches the cameras as built.
#[test]
fn a_calibration_short_of_views_visits_more_poses() {
    let out = std::env::temp_dir().join(format!("marvin_calibrate_more_{}", std::process::id()));
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_marvin"))
        .args(["calibrate", "cameras", concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/ideal/widgets.toml")])
        .args(["--seed", "8", "--json", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let views = doc["views"].as_array().unwrap();
    assert!(views.len() > 24, "only the planned {} poses were visited", views.len());
    let e = &doc["error"];
    for side in ["left", "right"] {
        let c = &e[side];
        let f = |k: &str| c[k].as_f64().unwrap().abs();
        assert!(f("fx_rel") < 0.0015 && f("fy_rel") < 0.0015, "{side}: {c}");
        assert!(f("cx_px") < 2.0 && f("cy_px") < 2.0, "{side}: {c}");
    }
    let g = |k: &str| e[k].as_f64().unwrap().abs();
    assert!(g("baseline_mm") < 0.2 && g("right_position_mm") < 0.6 && g("rotation_deg") < 0.15, "{e}");
    std::fs::remove_dir_all(&out).unwrap();
}

/// A calibration that cannot solve says why and keeps what it saw: with `--save-images` the
/// views are written (every pose visited, the extra ones too) and the error says where.
/// Three poses a round cannot give the views Zhang's method needs.
#[test]
fn a_calibration_that_fails_saves_its_views() {
    let dir = std::env::temp_dir().join(format!("marvin_calibrate_fails_{}", std::process::id()));
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_marvin"))
        .args(["calibrate", "cameras", concat!(env!("CARGO_MANIFEST_DIR"), "/worlds/ideal/widgets.toml")])
        .args(["--seed", "8", "--poses", "3", "--out"])
        .arg(dir.join("cams"))
        .arg("--save-images")
        .arg(dir.join("views"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{stderr}");
    assert!(stderr.contains("the views are saved in") && stderr.contains("poses gave the whole board"), "{stderr}");
    assert!(stderr.contains("more poses"), "no extra poses were visited: {stderr}");
    let listed: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("views/views.json")).unwrap()).unwrap();
    let views = listed["views"].as_array().unwrap();
    assert_eq!(views.len(), 9, "3 planned poses and two rounds of 3 more");
    for v in views {
        assert!(dir.join("views").join(v["left"].as_str().unwrap()).exists(), "{v}");
    }
    assert!(!dir.join("cams/cameras.json").exists(), "a failed calibration wrote a file");
    std::fs::remove_dir_all(&dir).unwrap();
}
