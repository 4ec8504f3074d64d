//! `marvin locate --left L --right R --cameras FILE`: the front end and the matcher on any
//! stereo pair, from any cameras: what was found (model, pose and grasp in the left camera's
//! frame, support), with no truth to compare with.

use super::edges::load_grey_noting;
use super::output::emit;
use anyhow::bail;
use marvin::engine::perception::{Pair, front_end, locate_parts, part_models};
use std::path::{Path, PathBuf};

/// The command's arguments in this form.
pub struct PairArgs {
    pub left: PathBuf,
    pub right: PathBuf,
    /// `marvin calibrate cameras`' cameras.json (or a scene.json from `marvin render`).
    pub cameras: PathBuf,
    pub models: Option<Vec<String>>,
    pub json: bool,
}

/// The cameras of a calibration file: the project's cameras.json, or a scene.json.
fn load_cameras(path: &Path) -> anyhow::Result<mesh::StereoCalibration> {
    match camera_calib::file::CamerasFile::load(path) {
        Ok(file) => Ok(file.stereo_calibration()),
        Err(cameras_err) => mesh::StereoCalibration::load(path).map_err(|_| {
            anyhow::anyhow!("{cameras_err:#} (nor is {} a scene.json from `marvin render`)", path.display())
        }),
    }
}

pub fn run(args: PairArgs) -> anyhow::Result<()> {
    let mut notes = Vec::new();
    let left = load_grey_noting(&args.left, &mut notes)?;
    let right = load_grey_noting(&args.right, &mut notes)?;
    if (left.width, left.height) != (right.width, right.height) {
        bail!(
            "{} is {}x{} but {} is {}x{}: a stereo pair must match",
            args.left.display(),
            left.width,
            left.height,
            args.right.display(),
            right.width,
            right.height
        );
    }
    let calib = load_cameras(&args.cameras)?;
    if (calib.left.width as usize, calib.left.height as usize) != (left.width, left.height) {
        bail!(
            "{}: the cameras are for {}x{} images, {} is {}x{}",
            args.cameras.display(),
            calib.left.width,
            calib.left.height,
            args.left.display(),
            left.width,
            left.height
        );
    }
    let library = mesh::Library::load_default()?;
    let mut models = part_models(&library);
    if let Some(names) = &args.models {
        for n in names {
            if !models.iter().any(|m| &m.name == n) {
                let known: Vec<&str> = models.iter().map(|m| m.name.as_str()).collect();
                bail!("--models: no part `{n}` in the library (it has: {})", known.join(", "));
            }
        }
        models.retain(|m| names.contains(&m.name));
    }
    let pair = Pair { left, right, calib };
    let fe = front_end(&pair);
    // No table: nothing says where it is in these cameras' frame.
    let located = locate_parts(&models, &pair, &fe, None);
    for note in &notes {
        eprintln!("note: {note}");
    }
    let rows: Vec<serde_json::Value> = located
        .iter()
        .map(|l| {
            serde_json::json!({
                "model": l.model,
                "cam_from_model": mesh::pose::PoseRecord::from(&l.cam_from_model),
                "grasp_cam_from_gripper": l.grasps.first().map(|(g, _)| mesh::pose::PoseRecord::from(g)),
                "support_fraction": l.support_fraction,
                "image_support": l.image_support,
            })
        })
        .collect();
    if args.json {
        return emit(&serde_json::json!({ "located": rows, "lines3d": fe.lines3d.len(), "notes": notes }).to_string());
    }
    emit(&format!("{} parts located from {} 3D lines:", located.len(), fe.lines3d.len()))?;
    for l in &located {
        let t = l.cam_from_model.translation.vector * 1e3;
        emit(&format!(
            "  {:<10} at ({:.1}, {:.1}, {:.1}) mm in the left camera's frame, {:.0}% of its edges matched, image support {:.2}",
            l.model,
            t.x,
            t.y,
            t.z,
            l.support_fraction * 100.0,
            l.image_support
        ))?;
    }
    Ok(())
}
