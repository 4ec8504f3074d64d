//! `marvin calibrate cameras`: camera calibration through the robot server (in-process on
//! loopback, or `--connect`ed), written as the project's JSON and a ROS `camera_info` YAML per
//! camera; with a server started here, the error against the cameras as built.

use super::calibrate::Cell;
use super::output::emit;
use anyhow::Context;
use camera_calib::file::CamerasFile;
use camera_calib::{Intrinsics, StereoSolution};
use marvin::engine::calibrate_cameras::{
    CameraCalibConfig, CameraCalibration, Unsolved, ViewRecord, calibrate_cameras,
};
use nalgebra::Isometry3;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// The command's arguments.
pub struct CamerasArgs {
    pub world: PathBuf,
    pub poses: usize,
    pub seed: Option<u64>,
    pub connect: Option<String>,
    /// Folder for cameras.json, left.yaml and right.yaml.
    pub out: PathBuf,
    pub json: bool,
    pub save_images: Option<PathBuf>,
    /// Where to record the calibration for rerun, if anywhere.
    pub rerun: Option<PathBuf>,
}

/// The cameras as built, from the world file (evaluation only, after the fact).
pub struct TrueRig {
    pub left: Intrinsics,
    pub right: Intrinsics,
    pub right_from_left: Isometry3<f64>,
}

impl TrueRig {
    pub fn of(world: &sim::world::WorldFile) -> TrueRig {
        let rig = sim::imaging::Imaging::new(world).rig;
        let intrinsics = |c: &sim::realism::CameraAsBuilt| Intrinsics {
            fx: c.pinhole.fx,
            fy: c.pinhole.fy,
            cx: c.pinhole.cx,
            cy: c.pinhole.cy,
            distortion: c.lens.distortion,
        };
        TrueRig {
            left: intrinsics(&rig.left),
            right: intrinsics(&rig.right),
            right_from_left: rig.right.pinhole.cam_from_world() * rig.left.pinhole.world_from_cam,
        }
    }

    /// The solution's errors: per camera fx, fy (relative), cx, cy (px), the distortion field's
    /// largest difference over the image with the true K (px); the baseline (mm), the right
    /// camera's position (mm) and the relative rotation (deg).
    pub fn errors(&self, s: &StereoSolution, size: [u32; 2]) -> Value {
        let camera = |got: &Intrinsics, want: &Intrinsics| {
            json!({
                "fx_rel": (got.fx - want.fx) / want.fx,
                "fy_rel": (got.fy - want.fy) / want.fy,
                "cx_px": got.cx - want.cx,
                "cy_px": got.cy - want.cy,
                "distortion_px_max": camera_calib::camera::distortion_difference_px(got, want, size),
            })
        };
        let (a, b) = (&s.right_from_left, &self.right_from_left);
        let centre = |p: &Isometry3<f64>| p.inverse().translation.vector;
        json!({
            "left": camera(&s.left, &self.left),
            "right": camera(&s.right, &self.right),
            "baseline_mm": (centre(a).norm() - centre(b).norm()) * 1e3,
            "right_position_mm": (centre(a) - centre(b)).norm() * 1e3,
            "rotation_deg": a.rotation.angle_to(&b.rotation).to_degrees(),
        })
    }
}

pub fn run(args: CamerasArgs) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&args.world)?;
    let seed = args.seed.unwrap_or(scn.world.seed);
    let config = CameraCalibConfig { poses: args.poses, seed, ..CameraCalibConfig::default() };
    if !args.json {
        eprintln!("calibrating the cameras: {} board poses, seed {seed}", config.poses);
    }
    let cell = Cell::start(&args.world, seed, args.connect.as_deref())?;
    let local = cell.local().is_some();
    let quiet = args.json;
    let mut progress = |line: &str| {
        if !quiet {
            eprintln!("  {line}");
        }
    };
    let keep_images = args.save_images.is_some() || args.rerun.is_some();
    let c = match run_once(cell, &scn.library, &config, keep_images, &mut progress) {
        Ok(c) => c,
        Err(e) => return Err(with_views_saved(e, args.save_images.as_deref())),
    };
    if let Some(path) = &args.rerun {
        let mut r =
            marvin::engine::recording::Recording::start(&marvin::engine::recording::Sink::File(path.to_path_buf()))?;
        r.camera_calibration(&c)?;
        r.finish()?;
        if !args.json {
            eprintln!("recorded the calibration in {} (open it with `rerun {}`)", path.display(), path.display());
        }
    }
    let file = CamerasFile::from_solution(&c.solution, c.size);
    file.save_all(&args.out)?;
    if let Some(dir) = &args.save_images {
        save_images(dir, &c.views)?;
    }
    let errors = local.then(|| TrueRig::of(&scn.world).errors(&c.solution, c.size));
    report(&args, &c, &file, errors)
}

/// One camera calibration on `cell`, which is stopped afterwards.
pub fn run_once(
    cell: Cell,
    library: &mesh::Library,
    config: &CameraCalibConfig,
    keep_images: bool,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<CameraCalibration> {
    let (mut client, hello) = cell.connect_greeted()?;
    let table_top = hello.table_top_base_m.unwrap_or(0.0);
    let outcome = calibrate_cameras(&mut client, table_top, library, config, keep_images, progress);
    client.bye()?;
    cell.stop()?;
    outcome
}

fn report(args: &CamerasArgs, c: &CameraCalibration, file: &CamerasFile, errors: Option<Value>) -> anyhow::Result<()> {
    let s = &c.solution;
    let used = s.views.iter().filter(|v| v.left_rms_px.is_some() || v.right_rms_px.is_some()).count();
    if args.json {
        let views: Vec<Value> = c
            .views
            .iter()
            .zip(&s.views)
            .map(|(v, fit)| json!({ "note": v.note, "left_rms_px": fit.left_rms_px, "right_rms_px": fit.right_rms_px }))
            .collect();
        let mut doc = serde_json::to_value(file)?;
        doc["views"] = json!(views);
        doc["out"] = json!(args.out.display().to_string());
        if let Some(e) = errors {
            doc["error"] = e;
        }
        return emit(&doc.to_string());
    }
    emit(&format!(
        "{used} of {} poses used; reprojection RMS {:.3} px (left {:.3}, right {:.3})",
        c.views.len(),
        s.rms_px,
        s.left_rms_px,
        s.right_rms_px
    ))?;
    for (name, k, sd) in [("left", &s.left, &s.left_sigma), ("right", &s.right, &s.right_sigma)] {
        let d = k.distortion.d();
        emit(&format!(
            "{name}: fx {:.2} +- {:.2}, fy {:.2} +- {:.2}, cx {:.2} +- {:.2}, cy {:.2} +- {:.2} px; k1 {:.4} +- {:.4}, k2 {:.4} +- {:.4}, p1 {:.5}, p2 {:.5}",
            k.fx, sd[0], k.fy, sd[1], k.cx, sd[2], k.cy, sd[3], d[0], sd[4], d[1], sd[5], d[2], d[3]
        ))?;
    }
    let t = s.right_from_left.inverse().translation.vector;
    emit(&format!(
        "right camera in the left's: baseline {:.2} +- {:.2} mm, at ({:.1}, {:.1}, {:.1}) mm",
        t.norm() * 1e3,
        s.rig_sigma[3..].iter().fold(0.0f64, |a, b| a.max(*b)) * 1e3,
        t.x * 1e3,
        t.y * 1e3,
        t.z * 1e3
    ))?;
    if let Some(e) = errors {
        emit(&format!("against the cameras as built: {}", serde_json::to_string(&e)?))?;
    }
    emit(&format!("wrote {}", args.out.display()))
}

/// A calibration that did not solve, its views saved first where `--save-images` asks for them
/// (they are what tells why: a board cut off by the image's edge, or hidden), and the error
/// saying where they are.
fn with_views_saved(e: anyhow::Error, dir: Option<&Path>) -> anyhow::Error {
    let (Some(dir), Some(unsolved)) = (dir, e.downcast_ref::<Unsolved>()) else { return e };
    match save_images(dir, &unsolved.views) {
        Ok(()) => e.context(format!("the views are saved in {}", dir.display())),
        Err(saving) => e.context(format!("and the views could not be saved: {saving:#}")),
    }
}

/// Every view taken, as lossless PNGs, with the board's geometry and the corners found beside
/// them (`views.json`), so that another tool can calibrate from the same images.
fn save_images(dir: &Path, views: &[ViewRecord]) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let mut listed = Vec::new();
    for (k, v) in views.iter().enumerate() {
        let Some((l, r)) = &v.images else { continue };
        let names = [format!("view{k:02}_left.png"), format!("view{k:02}_right.png")];
        for (img, name) in [l, r].into_iter().zip(&names) {
            img.save(dir.join(name)).with_context(|| format!("writing {}", dir.join(name).display()))?;
        }
        listed.push(json!({ "left": names[0], "right": names[1], "note": v.note, "corners": v.corners }));
    }
    let board = camera_calib::Board::LIBRARY;
    let doc = json!({
        "board": { "squares": board.squares, "inner_corners": board.inner(), "square_m": board.square_m,
                   "corner_order": "row by row from the corner whose square is light, x along the rows" },
        "views": listed,
    });
    let path = dir.join("views.json");
    std::fs::write(&path, serde_json::to_string_pretty(&doc)?).with_context(|| format!("writing {}", path.display()))
}
