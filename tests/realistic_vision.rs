//! Vision in the realistic cell (`worlds/widgets.toml`: lenses, two different sensors, a lamp
//! with shadows, gloss, a textured table, cameras mounted off their drawing), through cameras
//! measured from the board (`camera-calib/tests/fixtures/seed3_cameras.json`, a calibration of
//! this cell on tuning seed 3), as `marvin eval vision|locate --cameras` runs it.
//!
//! The scenes are 310001-310010, never used for any choice. The front end is held to the vision
//! issue's targets (0.95 of the disparities within 0.5 px, coverage 0.70): here 0.962 and
//! 0.744; the 3D lines it sets apart as shadows or texture must be so. The matcher has not earned its target (0.97 located) yet: since it no longer judges
//! a well-supported reading by its model's albedo it located 0.907 of the parts on tuning
//! seeds 101-120 (0.671 before) and 0.942 here (0.725 before), with no false report; the
//! limit below guards what it has (README, "The realistic cell").

mod common;

use std::process::Command;

const CAMERAS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/camera-calib/tests/fixtures/seed3_cameras.json");

fn eval(verb: &str) -> serde_json::Value {
    eval_on(verb, "worlds/widgets.toml", "310001", &[])
}

/// `marvin eval <verb> <world> --scenes 10 --seed <seed>` through the measured cameras.
fn eval_on(verb: &str, world: &str, seed: &str, more: &[&str]) -> serde_json::Value {
    let out = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(["eval", verb, world, "--scenes", "10", "--seed", seed, "--cameras", CAMERAS, "--json"])
        .args(more)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn the_front_end_matches_across_two_different_sensors() {
    let doc = eval("vision");
    let (within, coverage) = (doc["disparity_within_0_5px"].as_f64().unwrap(), doc["coverage"].as_f64().unwrap());
    eprintln!("within 0.5 px {within:.3}, coverage {coverage:.3}");
    assert!(within >= 0.95, "disparities within 0.5 px: {within:.3}");
    assert!(coverage >= 0.70, "coverage: {coverage:.3}");
    // Shadows and texture set apart (issue 48, part 3), judged against the true edges: here
    // 9.4 lines a scene, 0.91 of them on no part's edge, two thirds of such lines on the table.
    let apart = &doc["set_apart"];
    let (per_scene, off_edges) = (apart["per_scene"].as_f64().unwrap(), apart["off_edges"].as_f64().unwrap());
    eprintln!("set apart {per_scene:.1} lines a scene, {off_edges:.3} of them on no part's edge");
    assert!(per_scene >= 3.0, "lines set apart as shadows or texture: {per_scene:.1} a scene");
    assert!(off_edges >= 0.85, "of the lines set apart, on no part's edge: {off_edges:.3}");
}

#[test]
fn the_matcher_locates_parts_in_the_realistic_cell() {
    let doc = eval("locate");
    let (located, false_reports) =
        (doc["located_fraction"].as_f64().unwrap(), doc["false_positive_fraction"].as_f64().unwrap());
    eprintln!("located {located:.3}, false reports {false_reports:.3}");
    assert!(located >= 0.85, "located: {located:.3}");
    assert!(false_reports <= 0.03, "false reports: {false_reports:.3}");
}

/// Softer lenses than the cell's (`worlds/soft_lenses.toml`: Gaussian blur of 1.1 and 1.3 px
/// where the cell's is 0.45), as another camera or renderer may give. Canny's placement of
/// edgels beside parallel steps took every edge's wider profile for a neighbour's pull and
/// moved the edgels by up to a pixel, differently in each image; it now models each image's
/// blur as measured from its own edges (`vision::front_end::blur`). On tuning seeds 1-30
/// (these cameras): within 0.5 px 0.760 -> 0.939, coverage 0.495 -> 0.671, located (the table
/// from the images, as `marvin locate --left --right` finds it) 0.837 -> 0.943, 2 false
/// reports. Seeds 365001-365010, never used for a choice; the limits leave a margin for 10
/// scenes, each well above what the renderer's blur gave.
#[test]
fn vision_sees_through_softer_lenses() {
    let doc = eval_on("vision", "worlds/soft_lenses.toml", "365001", &[]);
    let (within, coverage) = (doc["disparity_within_0_5px"].as_f64().unwrap(), doc["coverage"].as_f64().unwrap());
    eprintln!("soft lenses: within 0.5 px {within:.3}, coverage {coverage:.3}");
    assert!(within >= 0.90, "disparities within 0.5 px: {within:.3}");
    assert!(coverage >= 0.60, "coverage: {coverage:.3}");
    let doc = eval_on("locate", "worlds/soft_lenses.toml", "365001", &["--table-from-images"]);
    let (located, false_reports) =
        (doc["located_fraction"].as_f64().unwrap(), doc["false_positive_fraction"].as_f64().unwrap());
    eprintln!("soft lenses: located {located:.3}, false reports {false_reports:.3}");
    assert!(located >= 0.88, "located: {located:.3}");
    assert!(false_reports <= 0.03, "false reports: {false_reports:.3}");
}

/// The main job in the realistic cell, as a new user runs it (`marvin run worlds/widgets.toml`):
/// the cameras calibrated from the board, the hand-eye transform through them, then the picks.
/// Seed 310011, never used for a choice. The limit was set from tuning seed 1's run (7 of 7
/// cleared) and what the arm loses regardless of vision (a slip in the jaws now and then): no
/// pick goes to the wrong model, and at most two parts are left.
#[test]
fn the_main_job_clears_the_realistic_table() {
    let doc = common::ok(
        common::marvin().args(["run", "worlds/widgets.toml", "--seed", "310011", "--json"]).output().unwrap(),
    );
    let truth = &doc["truth"];
    let (on_table, cleared) = (truth["on_table_at_start"].as_u64().unwrap(), truth["in_bin_at_end"].as_u64().unwrap());
    eprintln!("{cleared} of {on_table} cleared; calibration {}", doc["calibration_error"]);
    assert_eq!(truth["wrong_model_picks"].as_u64(), Some(0), "{truth}");
    assert!(cleared + 2 >= on_table, "{cleared} of {on_table} cleared");
}

/// Parts packed so that each one's fingers would touch the next: on tuning seed 112 the wedge,
/// the hex prism and the widget each blocked another once the rest were picked, and the run used
/// to stop with the three on the table. Where every part is blocked, the first that plans with
/// its neighbours left out is picked, its fingers pushing them aside: all seven are cleared,
/// one of them by such a pick, and none goes to the wrong model. Once Canny modelled each
/// image's blur (session 67) seed 112's parts are read a little differently and its run does
/// not come to that pass; the test runs tuning seed 120, whose last two parts, the U-channel
/// and the wedge, block each other.
#[test]
fn parts_that_block_each_other_are_picked_pushing_the_neighbours_aside() {
    let doc =
        common::ok(common::marvin().args(["run", "worlds/widgets.toml", "--seed", "120", "--json"]).output().unwrap());
    let truth = &doc["truth"];
    assert_eq!(truth["wrong_model_picks"].as_u64(), Some(0), "{truth}");
    assert_eq!(truth["in_bin_at_end"], truth["on_table_at_start"], "{truth}");
    let cycles = doc["cycles"].as_array().unwrap();
    let pushing: Vec<&serde_json::Value> = cycles.iter().filter(|c| c["pushing_neighbours"] == true).collect();
    assert!(!pushing.is_empty(), "no pick pushed its neighbours aside: {doc}");
    // Such a pick comes only after every part located was found blocked.
    for c in pushing {
        assert_eq!(c["unplannable"].as_u64().unwrap() as usize, c["located"].as_array().unwrap().len(), "{c}");
    }
}

/// A pose record of scene.json (`translation_m`, `rotation_xyzw`), read as the project reads it.
fn pose(v: &serde_json::Value) -> nalgebra::Isometry3<f64> {
    mesh::pose::iso_serde::deserialize(v).unwrap()
}

/// A pair from files, as a user's own cameras give one: `marvin render` writes a realistic
/// scene (seed 340002, never used for a choice), and `marvin locate --left --right --cameras`
/// sees only the two PNGs and the measured cameras. Its reports are then checked here against
/// the scene's truth (scene.json, in the true left camera's frame): most of the parts found,
/// each report within 5 mm of a part of its model; `--truth` and `eval pairs` count them alike.
#[test]
fn a_pair_from_files_is_located_through_measured_cameras() {
    let scenes = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("realistic_pairs");
    let dir = scenes.join("340002");
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_marvin"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .args(args)
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        out.stdout
    };
    // `--scenes` renders each scene into a folder named by its seed, as `eval pairs` reads them.
    run(&["render", "worlds/widgets.toml", "--seed", "340002", "--scenes", "1", "--out", scenes.to_str().unwrap()]);
    let (left, right) = (dir.join("left.png"), dir.join("right.png"));
    let doc: serde_json::Value = serde_json::from_slice(&run(&[
        "locate",
        "--left",
        left.to_str().unwrap(),
        "--right",
        right.to_str().unwrap(),
        "--cameras",
        CAMERAS,
        "--json",
    ]))
    .unwrap();
    let scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("scene.json")).unwrap()).unwrap();
    let cam_from_world = pose(&scene["as_built"]["left"]["pinhole"]["world_from_cam"]).inverse();
    let truths: Vec<(String, nalgebra::Vector3<f64>)> = scene["objects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| {
            (
                o["model"].as_str().unwrap().to_string(),
                (cam_from_world * pose(&o["world_from_model"])).translation.vector,
            )
        })
        .collect();
    let located = doc["located"].as_array().unwrap();
    let right_ones = located
        .iter()
        .filter(|l| {
            let at = pose(&l["cam_from_model"]).translation.vector;
            truths.iter().any(|(m, t)| m == l["model"].as_str().unwrap() && (t - at).norm() < 0.005)
        })
        .count();
    eprintln!(
        "{} reports, {right_ones} within 5 mm of a part of their model, of {} parts",
        located.len(),
        truths.len()
    );
    assert!(right_ones + 2 >= truths.len(), "{right_ones} of {} parts found: {doc}", truths.len());
    // With no cell layout, the matcher took the table's top from the 3D lines: the true top
    // (the world's z = 0) at the workspace's centre lies within 3 mm of it.
    let top = &doc["table_top"]["table"];
    let up = nalgebra::Vector3::from_iterator(top["up"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()));
    let centre = cam_from_world * nalgebra::Point3::origin();
    let height = up.dot(&centre.coords) + top["camera_height_m"].as_f64().unwrap();
    assert!(height.abs() < 0.003, "the true table's centre {:.1} mm off the top found", height * 1e3);
    assert_eq!(right_ones, located.len(), "a report not on a part of its model: {doc}");

    // `--truth scene.json` compares after the matcher has run: the same reports, each with the
    // distance to the nearest part of its model that this test measures itself.
    let scene_json = dir.join("scene.json");
    let pair = ["locate", "--left", left.to_str().unwrap(), "--right", right.to_str().unwrap(), "--cameras", CAMERAS];
    let args: Vec<&str> = pair.iter().copied().chain(["--json", "--truth", scene_json.to_str().unwrap()]).collect();
    let judged: serde_json::Value = serde_json::from_slice(&run(&args)).unwrap();
    assert_eq!(judged["located"], doc["located"], "the truth file changes nothing the matcher does");
    let reports = judged["truth"]["reports"].as_array().unwrap();
    assert_eq!(reports.len(), located.len());
    for (l, r) in located.iter().zip(reports) {
        let at = pose(&l["cam_from_model"]).translation.vector;
        let nearest = truths
            .iter()
            .filter(|(m, _)| m == l["model"].as_str().unwrap())
            .map(|(_, t)| (t - at).norm() * 1e3)
            .fold(f64::MAX, f64::min);
        let said = r["pos_err_mm"].as_f64().unwrap();
        assert!((said - nearest).abs() < 0.01, "{said} mm said, {nearest} mm measured: {r}");
    }
    // It counts as `eval locate` counts: each object in view (by the depth map beside the
    // file) located or not, every report here correct.
    let t = &judged["truth"];
    assert_eq!(t["in_view_from_depth"], true, "{t}");
    let in_view = t["in_view"].as_u64().unwrap() as usize;
    assert!(in_view <= truths.len() && in_view + 2 >= truths.len(), "{in_view} of {} objects in view", truths.len());
    assert_eq!(t["located"].as_u64().unwrap() as usize + t["not_located"].as_array().unwrap().len(), in_view, "{t}");
    assert_eq!(t["false_reports"], 0, "{t}");

    // `eval pairs` reads every scene folder of a directory the same way and sums them.
    let summed: serde_json::Value =
        serde_json::from_slice(&run(&["eval", "pairs", scenes.to_str().unwrap(), "--cameras", CAMERAS, "--json"]))
            .unwrap();
    let read = &summed["scenes_read"][0];
    assert_eq!(
        (read["located"].clone(), read["in_view"].clone()),
        (t["located"].clone(), t["in_view"].clone()),
        "{summed}"
    );
    assert_eq!(read["seed"], 340002);
    // The front end's fate of the left edgels on the parts' edges, against the truth: on the
    // cell's own images most are matched within 0.5 px of the true disparity (0.51 and 0.46 of
    // them on tuning seeds 7001-7040 of widgets and of piled parts) and few further off (0.012,
    // 0.017).
    let fates = &summed["part_edgels"];
    assert!(fates["counted"].as_u64().unwrap() > 1000, "{fates}");
    assert!(fates["matched_within_0_5px"].as_f64().unwrap() > 0.45, "{fates}");
    assert!(fates["matched_off"].as_f64().unwrap() < 0.02, "{fates}");
    let fraction = t["located"].as_f64().unwrap() / in_view as f64;
    assert!((summed["located_fraction"].as_f64().unwrap() - fraction).abs() < 1e-12, "{summed}");

    // A truth file that is not one is refused, naming it and the field at fault.
    let bad = dir.join("not_a_scene.json");
    std::fs::write(&bad, r#"{"objects": [{"model": "block"}], "calibration": {"left": {"world_from_cam": {"translation_m": [0, 0, 0], "rotation_xyzw": [0, 0, 0, 1]}}}}"#).unwrap();
    let args: Vec<&str> = pair.iter().copied().chain(["--truth", bad.to_str().unwrap()]).collect();
    let o = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(&args)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("not_a_scene.json") && e.contains("objects[0].world_from_model"), "{e}");
    // A scene folder without its right image is named.
    let half = scenes.join("half");
    std::fs::create_dir_all(&half).unwrap();
    std::fs::copy(&left, half.join("left.png")).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .args(["eval", "pairs", scenes.to_str().unwrap(), "--cameras", CAMERAS])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("half") && e.contains("right.png"), "{e}");
    std::fs::remove_dir_all(&half).unwrap();
    // Without the depth map beside scene.json, every object counts as in view, and it says so.
    let bare = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("realistic_pairs_bare");
    std::fs::create_dir_all(bare.join("340002")).unwrap();
    for f in ["left.png", "right.png", "scene.json"] {
        std::fs::copy(dir.join(f), bare.join("340002").join(f)).unwrap();
    }
    let summed: serde_json::Value =
        serde_json::from_slice(&run(&["eval", "pairs", bare.to_str().unwrap(), "--cameras", CAMERAS, "--json"]))
            .unwrap();
    let read = &summed["scenes_read"][0];
    assert_eq!(read["in_view_from_depth"], false, "{summed}");
    assert_eq!(read["in_view"].as_u64().unwrap() as usize, truths.len(), "{summed}");
    // `--doubt` judges which reports a turn of the part fits as well, and changes none of them.
    let args = ["eval", "pairs", bare.to_str().unwrap(), "--cameras", CAMERAS, "--doubt", "--json"];
    let doubted: serde_json::Value = serde_json::from_slice(&run(&args)).unwrap();
    for key in ["located_fraction", "false_positive_fraction", "scenes_read"] {
        assert_eq!(doubted[key], summed[key], "{key}");
    }
    let (right, wrong) = (&doubted["in_doubt"]["right_reports"], &doubted["in_doubt"]["false_reports"]);
    let reports = read["reports"].as_u64().unwrap();
    assert!(right.as_u64().unwrap() + wrong.as_u64().unwrap() <= reports, "{doubted}");
    let marked = doubted["false_reports"].as_array().unwrap();
    assert!(marked.iter().all(|f| f["report"]["in_doubt"].is_boolean()), "{doubted}");
    assert!(summed["in_doubt"].is_null(), "judged only when asked: {summed}");
}
