//! A seeded scene through the front end, as `marvin locate` and the `eval` verbs take it: settled,
//! rendered as the world's preset draws it, and run through the sliced front end with the
//! cameras vision is given (the world file's, or measured ones placed where the left camera
//! truly stands); and the library's models as the matcher seeks them.

use sim::{Scenario, Scene};

/// A seeded scene taken through rendering and the (sliced) front end.
pub struct Pipeline {
    pub scene: Scene,
    pub left: sim::render::Frame,
    pub right: sim::render::Frame,
    pub front_end: vision::front_end::FrontEnd,
    /// Whether the scene came to rest (a warning was printed if not).
    pub settled: bool,
    /// The calibration vision was given, and the true cameras.
    pub cams: marvin::eval::truth::EvalCameras,
}

/// The front end's Canny parameters, deblurred or not.
pub fn canny_params(deblur: bool) -> vision::CannyParams {
    vision::CannyParams { deblur, ..vision::CannyParams::default() }
}

/// The cameras vision is given, and the true ones: the world file's, or `cameras`' measured ones.
pub fn eval_cameras(
    imaging: &sim::imaging::Imaging,
    cameras: Option<&std::path::Path>,
) -> anyhow::Result<marvin::eval::truth::EvalCameras> {
    Ok(match cameras {
        Some(path) => marvin::eval::truth::EvalCameras::measured(imaging, &super::calibrate::load_cameras(path)?),
        None => marvin::eval::truth::EvalCameras::of(imaging),
    })
}

/// Settles the scene of `seed`, renders it as `imaging` has the cell, and runs the sliced
/// front end on it with the cameras `cams` gives vision (searching no disparity under the
/// table, where `cam_from_table` places it, as a run does).
pub fn run_pipeline(
    scn: &Scenario,
    imaging: &sim::imaging::Imaging,
    seed: u64,
    canny: &vision::CannyParams,
    cams: &marvin::eval::truth::EvalCameras,
    cam_from_table: Option<&nalgebra::Isometry3<f64>>,
) -> Pipeline {
    let cams = cams.clone();
    let calib = &cams.vision;
    let (scene, settled) = super::output::settle(scn, seed);
    let (l, r) = imaging.render_stereo(&scene.render_scene(&scn.library, imaging), seed);
    let left = vision::GreyImage::new(l.width, l.height, l.image.clone()).expect("a rendered frame is whole");
    let right = vision::GreyImage::new(r.width, r.height, r.image.clone()).expect("a rendered frame is whole");
    let workspace = marvin::engine::perception::workspace(cam_from_table);
    let front_end = vision::front_end::slices::run_sliced(&left, &right, calib, &workspace, canny, 8);
    Pipeline { scene, left: l, right: r, front_end, settled, cams }
}

/// The library's models as the matcher sees them (the calibration tools are not sought).
pub fn matcher_models(library: &mesh::Library, only: Option<&[String]>) -> Vec<vision::matcher::MatcherModel> {
    library
        .parts()
        .filter(|m| only.is_none_or(|o| o.contains(&m.name)))
        .map(vision::matcher::MatcherModel::from_model)
        .collect()
}
