//! The vision front end on rendered scenes, against ground truth.
//!
//! Run on the ideal copy of the world (`worlds/ideal/`): these figures were measured in the ideal
//! cell and vision has not yet earned them in the realistic one (README, "The realistic cell").

use marvin::eval::truth::{EvalCameras, TruthScene};
use marvin::eval::{ArmMask, DisparityStats, disparity_stats};
use sim::render::{Light, RenderScene, render_stereo};
use sim::{Scenario, Scene};
use std::path::Path;

fn run_scene(world: &str, seed: u64) -> (DisparityStats, usize) {
    let scn = Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(world)).unwrap();
    let calib = sim::rig::calibration(&scn.world.cameras);
    let scene = Scene::settle(&scn, seed);
    let rs = RenderScene::new(scene.world_meshes(&scn.library), &Light::from(&scn.world.light));
    let (l, r) = render_stereo(&rs, &calib, scn.world.render.noise_sigma, seed);
    let arm = ArmMask::from_ids(l.width, l.height, &l.ids);
    let left = vision::GreyImage::new(l.width, l.height, l.image).unwrap();
    let right = vision::GreyImage::new(r.width, r.height, r.image).unwrap();
    let fe = marvin::front_end::run(&left, &right, &calib, &Default::default(), &vision::CannyParams::default());
    let truth = TruthScene::new(scene.world_meshes(&scn.library).map(|(_, m)| m));
    (disparity_stats(&fe, &truth, &EvalCameras::exact(&calib), &arm).0, fe.left.edgels.len())
}

/// Two objects apart, sensor noise on: no ambiguity for PMF to get wrong, so this guards the
/// geometry (Canny, rectification, candidate disparities) rather than the matching strategy.
#[test]
fn disparities_of_an_uncluttered_scene_are_right() {
    let (stats, edgels) = run_scene("worlds/ideal/two_objects.toml", 1);
    eprintln!("two objects: {stats:?} of {edgels} left edgels");
    assert!(stats.evaluated >= 400, "only {} matches", stats.evaluated);
    assert!(stats.within_fraction() >= 0.97, "{:.3} within 0.5 px", stats.within_fraction());
    assert_eq!(stats.wrong, 0, "wrong matches in a scene without ambiguity");
}

/// The front-end issue's acceptance figures, over 20 seeded clutter scenes of the default world
/// from seeds 360001-360020, never used to choose a parameter (the test ran on 10001-10020 until
/// that range had served for choices; there it measured 0.956 within 0.5 px, 0.011 wrong, ends
/// 0.29 / 1.73 mm, coverage 0.700, at the coverage target's edge). The limits are the issue's
/// targets, unchanged. (5 scenes are too few to judge these figures: the first 5 of 10001- gave
/// 0.938 and 0.675.)
#[test]
fn the_default_world_meets_the_front_end_targets() {
    let scn = Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("worlds/ideal/widgets.toml")).unwrap();
    let calib = sim::rig::calibration(&scn.world.cameras);
    let light = Light::from(&scn.world.light);
    let (mut disparities, mut lines) = (DisparityStats::default(), marvin::eval::LineStats::default());
    for seed in 360001..=360020 {
        let scene = Scene::settle(&scn, seed);
        let rs = RenderScene::new(scene.world_meshes(&scn.library), &light);
        let (l, r) = render_stereo(&rs, &calib, scn.world.render.noise_sigma, seed);
        let left = vision::GreyImage::new(l.width, l.height, l.image.clone()).unwrap();
        let right = vision::GreyImage::new(r.width, r.height, r.image).unwrap();
        // The front end as shipped: 8 slices, joined.
        let fe = vision::front_end::slices::run_sliced(
            &left,
            &right,
            &calib,
            &Default::default(),
            &vision::CannyParams::default(),
            8,
        );
        let truth = TruthScene::new(scene.world_meshes(&scn.library).map(|(_, m)| m));
        let arm = ArmMask::from_ids(l.width, l.height, &l.ids);
        disparities.add(&disparity_stats(&fe, &truth, &EvalCameras::exact(&calib), &arm).0);
        lines.add(&marvin::eval::line_stats(&fe, &scene, &scn.library, &EvalCameras::exact(&calib), &l.depth, &arm));
    }
    let (within, wrong) = (disparities.within_fraction(), disparities.wrong_fraction());
    let (median, p90, coverage) = (lines.endpoint_quantile(0.5), lines.endpoint_quantile(0.9), lines.coverage());
    eprintln!("within 0.5 px {within:.3}, wrong {wrong:.3}, ends {median:.2} / {p90:.2} mm, coverage {coverage:.3}");
    assert!(within >= 0.95, "disparity within 0.5 px: {within:.3}");
    assert!(wrong <= 0.02, "wrong matches: {wrong:.3}");
    assert!(median <= 1.0, "endpoint error median {median:.2} mm");
    assert!(p90 <= 3.0, "endpoint error p90 {p90:.2} mm");
    assert!(coverage >= 0.7, "coverage {coverage:.3}");
}

/// Slicing must not change the answer: nearly every 3D line of the whole-image front end in the
/// workspace has a twin from the 8-slice run with both ends within 0.5 mm. (The robot's column,
/// which the cameras see from the table to the image's top, is left out: its silhouettes are
/// wrong in both runs, see `marvin::eval::ArmMask`, and the runs are wrong differently.)
#[test]
fn sliced_and_whole_image_runs_agree() {
    let scn = Scenario::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("worlds/ideal/widgets.toml")).unwrap();
    let calib = sim::rig::calibration(&scn.world.cameras);
    let light = Light::from(&scn.world.light);
    let (mut agree, mut total) = (0, 0);
    for seed in [2, 6, 9] {
        let scene = Scene::settle(&scn, seed);
        let (l, r) = render_stereo(&RenderScene::new(scene.world_meshes(&scn.library), &light), &calib, 1.5, seed);
        let arm = ArmMask::from_ids(l.width, l.height, &l.ids);
        let on_arm = |p: [f64; 3], q: [f64; 3]| {
            let mid = nalgebra::Point3::new((p[0] + q[0]) / 2.0, (p[1] + q[1]) / 2.0, (p[2] + q[2]) / 2.0);
            calib.left.project_cam(&mid).is_some_and(|px| arm.covers(px.x, px.y))
        };
        let left = vision::GreyImage::new(l.width, l.height, l.image).unwrap();
        let right = vision::GreyImage::new(r.width, r.height, r.image).unwrap();
        let params = vision::CannyParams::default();
        let whole = marvin::front_end::run(&left, &right, &calib, &Default::default(), &params);
        let sliced = vision::front_end::slices::run_sliced(&left, &right, &calib, &Default::default(), &params, 8);
        let near = |p: [f64; 3], q: [f64; 3]| (0..3).map(|i| (p[i] - q[i]).powi(2)).sum::<f64>().sqrt() <= 5e-4;
        for a in whole.lines3d.iter().filter(|a| !on_arm(a.a, a.b)) {
            total += 1;
            let twin =
                sliced.lines3d.iter().any(|b| (near(a.a, b.a) && near(a.b, b.b)) || (near(a.a, b.b) && near(a.b, b.a)));
            agree += usize::from(twin);
        }
    }
    let fraction = agree as f64 / total as f64;
    eprintln!("sliced vs whole: {agree} of {total} 3D lines agree ({fraction:.3})");
    assert!(total > 100, "only {total} lines to compare");
    assert!(fraction >= 0.98, "only {fraction:.3} of 3D lines agree");
}
