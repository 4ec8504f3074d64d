//! End to end: `marvin edges` and `marvin stereo` on rendered images, and their errors; a run's
//! captures saved and looked at again with `marvin locate --left --right`.
//!
//! Run on the ideal copy of the world (`worlds/ideal/`): these figures were measured in the ideal
//! cell and vision has not yet earned them in the realistic one (README, "The realistic cell").

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
        let out = marvin(&["render", "worlds/ideal/widgets.toml", "--seed", "3", "--out", dir.to_str().unwrap()]);
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

/// The 3D lines `marvin stereo` prints lie on the surfaces the renderer drew: each line's
/// midpoint, projected into the left image, is as deep as the depth map there (within 2 mm of
/// the nearest and farthest surface in a 7x7 window, as a line on an occluding edge lies on the
/// nearer side). Lines on the robot's column (ids >= 1000, whose silhouettes the two cameras see
/// differently) are left out. Measured on this scene: 69 of 75 lines (0.92; the other six float
/// 4-50 mm off the surfaces, wrong disparities the vision issue is about); the limit, 0.88,
/// lets three more go wrong and fails if disparities or the triangulation do.
#[test]
fn stereo_json_lines_lie_on_the_rendered_surfaces() {
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
    assert!(doc["matches"].as_array().unwrap().len() > 500);
    let calib = mesh::StereoCalibration::load(&dir.join("scene.json")).unwrap();
    let (on_surface, judged) = lines_on_surfaces(&doc, &dir, &calib.left);
    let fraction = on_surface as f64 / judged.max(1) as f64;
    eprintln!("{on_surface} of {judged} 3D lines on the rendered surfaces ({fraction:.3})");
    assert!(judged >= 30, "only {judged} lines to judge");
    assert!(fraction >= 0.88, "{on_surface} of {judged} 3D lines lie on the rendered surfaces");
}

/// Of the 3D lines in `stereo --json`'s output, how many lie on the rendered surfaces, and how
/// many could be judged: each line's midpoint, projected into the left image through `left`,
/// must be as deep as the depth map there (within 2 mm of the nearest and farthest surface in a
/// 7x7 window, as a line on an occluding edge lies on the nearer side); lines on the robot's
/// column (ids >= 1000, whose silhouettes the two cameras see differently) are left out.
fn lines_on_surfaces(doc: &serde_json::Value, dir: &Path, left: &mesh::PinholeCamera) -> (usize, usize) {
    let depth = image::open(dir.join("depth_left.png")).unwrap().into_luma16();
    let ids = image::open(dir.join("ids_left.png")).unwrap().into_luma16();
    let xyz = |v: &serde_json::Value| -> [f64; 3] { std::array::from_fn(|k| v[k].as_f64().unwrap()) };
    let (mut on_surface, mut judged) = (0, 0);
    for line in doc["lines3d"].as_array().unwrap() {
        let (a, b) = (xyz(&line["a"]), xyz(&line["b"]));
        let mid = nalgebra::Point3::from(std::array::from_fn::<f64, 3, _>(|k| (a[k] + b[k]) / 2.0));
        let Some(px) = left.project_cam(&mid) else { continue };
        let (u, v) = (px.x.round() as i64, px.y.round() as i64);
        let window: Vec<(u32, u32)> = (-3..=3)
            .flat_map(|dy| (-3..=3).map(move |dx| (u + dx, v + dy)))
            .filter(|&(x, y)| x >= 0 && y >= 0 && x < depth.width() as i64 && y < depth.height() as i64)
            .map(|(x, y)| (x as u32, y as u32))
            .collect();
        if window.is_empty() || window.iter().any(|&(x, y)| ids.get_pixel(x, y)[0] >= 1000) {
            continue;
        }
        let depths: Vec<f64> =
            window.iter().map(|&(x, y)| depth.get_pixel(x, y)[0]).filter(|&d| d > 0).map(|d| d as f64 * 1e-4).collect();
        let (near, far) = depths.iter().fold((f64::MAX, f64::MIN), |(n, f), &d| (n.min(d), f.max(d)));
        judged += 1;
        on_surface += usize::from(mid.z >= near - 0.002 && mid.z <= far + 0.002);
    }
    (on_surface, judged)
}

/// The same on the realistic cell's images, with the cameras `marvin calibrate cameras`
/// measured (the fixture of `camera-calib/tests/`: this world's rig): edge locations corrected
/// for the lenses before rectification put 3D lines on the surfaces, where the cameras as the
/// world file draws them do not. Measured: 12 of 14 lines (the nominal cameras: 1 of 8). The
/// realistic front end matches far fewer edgels than the ideal (issue 48), hence few lines.
#[test]
fn stereo_through_calibrated_lenses_puts_lines_on_the_surfaces() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_vision_realistic");
    let out = marvin(&["render", "worlds/widgets.toml", "--seed", "3", "--out", path(&dir)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let cameras = Path::new(env!("CARGO_MANIFEST_DIR")).join("camera-calib/tests/fixtures/seed3_cameras.json");
    let (left_png, right_png) = (dir.join("left.png"), dir.join("right.png"));
    let args =
        ["stereo", "--left", path(&left_png), "--right", path(&right_png), "--cameras", path(&cameras), "--json"];
    let out = marvin(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let left = camera_calib::file::CamerasFile::load(&cameras).unwrap().stereo_calibration().left;
    let (on_surface, judged) = lines_on_surfaces(&doc, &dir, &left);
    eprintln!("{on_surface} of {judged} 3D lines on the rendered surfaces");
    assert!(judged >= 10 && on_surface as f64 >= 0.75 * judged as f64, "{on_surface} of {judged}");
    let bad = dir.join("bad_cameras.json");
    std::fs::write(&bad, "{\"format\": \"marvin-cameras/1\"}").unwrap();
    let out = marvin(&[
        "stereo",
        "--left",
        path(&dir.join("left.png")),
        "--right",
        path(&dir.join("right.png")),
        "--cameras",
        path(&bad),
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("bad_cameras.json"), "{stderr}");
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
    let out = marvin(&["locate", "worlds/ideal/widgets.toml", "--seed", "1", "--json", "--out", path(&dir)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let located = doc["located"].as_array().unwrap();
    assert!(located.iter().any(|l| l["correct"] == true), "nothing located correctly: {doc}");
    let xyz = |v: &serde_json::Value| -> [f64; 3] { std::array::from_fn(|k| v[k].as_f64().unwrap()) };
    // The 3D lines each correct report rests on lie along the true object's feature edges:
    // their midpoints' distance from the true wireframe (scene.json's pose; measured on this
    // scene over 54 lines: median 0.10 mm, worst 1.12 mm) is within 0.3 mm at the median and
    // 2 mm at worst (the matcher accepts lines within 3 mm of its own pose).
    let render = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_locate_render");
    let r = marvin(&["render", "worlds/ideal/widgets.toml", "--seed", "1", "--out", path(&render)]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(render.join("scene.json")).unwrap()).unwrap();
    let calib = mesh::StereoCalibration::load(&render.join("scene.json")).unwrap();
    let library = mesh::Library::load_default().unwrap();
    let mut distances = Vec::new();
    for l in located.iter().filter(|l| l["correct"] == true) {
        assert!(l["grasp_cam_from_gripper"]["rotation_xyzw"].is_array());
        let truth = scene["objects"].as_array().unwrap().iter().find(|o| o["id"] == l["object"]).unwrap();
        let pose: mesh::pose::PoseRecord = serde_json::from_value(truth["world_from_model"].clone()).unwrap();
        let cam_from_model = calib.left.cam_from_world() * nalgebra::Isometry3::from(&pose);
        let model = library.get(l["model"].as_str().unwrap()).unwrap();
        for s in l["scene_lines"].as_array().unwrap() {
            let (a, b) = (xyz(&s["a_m"]), xyz(&s["b_m"]));
            let mid = nalgebra::Point3::from(std::array::from_fn::<f64, 3, _>(|k| (a[k] + b[k]) / 2.0));
            let d = model
                .wireframe
                .iter()
                .map(|e| distance_to_segment(&mid, &(cam_from_model * e.a), &(cam_from_model * e.b)))
                .fold(f64::MAX, f64::min);
            distances.push(d * 1e3);
        }
    }
    distances.sort_by(f64::total_cmp);
    eprintln!("support lines from the true wireframe, mm: {distances:.2?}");
    assert!(distances.len() >= 10, "only {} support lines", distances.len());
    assert!(distances[distances.len() / 2] <= 0.3, "median {:.2} mm", distances[distances.len() / 2]);
    assert!(distances[distances.len() - 1] <= 2.0, "worst {:.2} mm", distances[distances.len() - 1]);
    assert!(doc["missed"].is_array());
    assert!(dir.join("located.png").exists());
    let bad = marvin(&["locate", "worlds/ideal/widgets.toml", "--models", "teapot"]);
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("teapot"));
}

/// Seed 58 hides most of its L-bracket behind other parts; `locate` reports it missed, with the
/// fraction of its edges in view and the evidence its true pose finds. Measured: 32% of its
/// edges visible; at the truth 0.159 of its wireframe in 3D lines along 2 model lines, and only
/// 0.41 of it on image edgels, short of the 0.5 a report needs: the evidence says why it was
/// missed. (Seed 6's L-bracket, 20% visible, was this test's case until the stereo polish put
/// the reading the table look had made of it, 5.1 deg off, onto it.)
#[test]
fn locate_says_how_much_of_a_missed_object_was_visible() {
    let out = marvin(&["locate", "worlds/ideal/widgets.toml", "--seed", "58", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let missed = doc["missed"].as_array().unwrap();
    let bracket = missed.iter().find(|m| m["model"] == "l_bracket").unwrap_or_else(|| panic!("{doc}"));
    let figure = |key: &str| bracket[key].as_f64().unwrap_or_else(|| panic!("{key}: {bracket}"));
    assert!((0.25..0.4).contains(&figure("visible_fraction")), "{bracket}");
    let bars = vision::matcher::MatchParams::default();
    assert!((0.05..0.3).contains(&figure("support_fraction_at_truth")), "{bracket}");
    assert!(bracket["supported_lines_at_truth"].as_u64().unwrap() >= 2, "{bracket}");
    assert!(figure("image_support_at_truth") < bars.min_image_support, "{bracket}");
    assert!(figure("image_support_at_truth") > 0.15, "the bracket's visible edges are on edgels: {bracket}");
}

fn distance_to_segment(p: &nalgebra::Point3<f64>, a: &nalgebra::Point3<f64>, b: &nalgebra::Point3<f64>) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-18)).clamp(0.0, 1.0);
    (p - (a + ab * t)).norm()
}

/// `marvin run --save-captures DIR` writes each cycle's pair as the cameras sent it, and `marvin
/// locate --left --right` on a saved pair finds the parts the run located in that cycle.
#[test]
fn a_runs_captures_are_saved_and_located_again() {
    let fixture = "tests/fixtures/ideal_seed3";
    let (cameras, hand_eye) = (format!("{fixture}/cameras.json"), format!("{fixture}/hand_eye.json"));
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("cli_vision_captures");
    let _ = std::fs::remove_dir_all(&dir);
    let out = marvin(&[
        "run",
        "worlds/ideal/widgets.toml",
        "--seed",
        "3",
        "--cameras",
        &cameras,
        "--hand-eye",
        &hand_eye,
        "--max-cycles",
        "2",
        "--save-captures",
        path(&dir),
        "--json",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let run: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let models = |located: &serde_json::Value| {
        let mut m: Vec<String> =
            located.as_array().unwrap().iter().map(|l| l["model"].as_str().unwrap().to_string()).collect();
        m.sort();
        m
    };
    let cycles = run["cycles"].as_array().unwrap();
    assert_eq!(cycles.len(), 2);
    for (k, cycle) in cycles.iter().enumerate() {
        let (left, right) =
            (dir.join(format!("cycle_{:02}_left.png", k + 1)), dir.join(format!("cycle_{:02}_right.png", k + 1)));
        for p in [&left, &right] {
            let img = image::open(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            assert_eq!((img.width(), img.height(), img.color()), (512, 512, image::ColorType::L8), "{}", p.display());
        }
        let out = marvin(&["locate", "--left", path(&left), "--right", path(&right), "--cameras", &cameras, "--json"]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let again: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(models(&again["located"]), models(&cycle["located"]), "cycle {}", k + 1);
    }
    assert!(!dir.join("cycle_03_left.png").exists(), "a third cycle was never captured");
}
