//! `marvin locate --left L --right R --cameras FILE`: the front end and the matcher on any
//! stereo pair, from any cameras: what was found (model, pose and grasp in the left camera's
//! frame, support); compared with a truth file (`--truth`, a scene.json of `marvin render`)
//! only when one is given, after the matcher has run.

use super::edges::load_grey_noting;
use super::output::emit;
use anyhow::{Context, bail};
use marvin::engine::perception::{Pair, front_end, locate_parts, part_models};
use nalgebra::Isometry3;
use std::path::{Path, PathBuf};

/// The command's arguments in this form.
pub struct PairArgs {
    pub left: PathBuf,
    pub right: PathBuf,
    /// `marvin calibrate cameras`' cameras.json (or a scene.json from `marvin render`).
    pub cameras: PathBuf,
    pub models: Option<Vec<String>>,
    pub json: bool,
    /// A scene.json of `marvin render`, to compare with.
    pub truth: Option<PathBuf>,
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
    // Read before the matcher runs, so that a bad file costs nothing; used only after it.
    let truth = args.truth.as_deref().map(SceneTruth::load).transpose()?;
    let pair = Pair { left, right, calib };
    // No cell layout says where the table is in these cameras' frame: the matcher takes it from
    // the scene's own 3D lines (the front end searched without it).
    let mut fe = front_end(&pair, None);
    let top = vision::front_end::table_top::find(&fe.lines3d);
    let table_note = match &top {
        Some(t) => format!(
            "the table's top found on {} 3D lines ({:.0} mm of them), {:.1} mm below the left camera",
            t.lines.len(),
            t.length_m * 1e3,
            t.table.camera_height_m * 1e3
        ),
        None => "no table's top found in the 3D lines: the matcher looks without one".to_string(),
    };
    notes.push(table_note);
    // With the top known, the lines on it with soft edges (shadows, texture) are set apart.
    if let Some(t) = &top {
        fe.set_apart_soft_lines(&t.table);
        notes.push(format!("{} 3D lines on the table's top set apart as shadows or texture", fe.set_apart.len()));
    }
    let located = locate_parts(&models, &pair, &fe, top.as_ref().map(|t| t.table.cam_from_table()).as_ref());
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
    let compared = truth.as_ref().map(|t| t.compare(&library, &located));
    if args.json {
        let table = top
            .as_ref()
            .map(|t| serde_json::json!({ "table": t.table, "lines": t.lines.len(), "length_m": t.length_m }));
        let mut out = serde_json::json!({ "located": rows, "lines3d": fe.lines3d.len(), "lines3d_set_apart": fe.set_apart.len(), "table_top": table, "notes": notes });
        if let Some(c) = &compared {
            out["truth"] = c.to_json();
        }
        return emit(&out.to_string());
    }
    emit(&format!("{} parts located from {} 3D lines:", located.len(), fe.lines3d.len()))?;
    for (k, l) in located.iter().enumerate() {
        let t = l.cam_from_model.translation.vector * 1e3;
        let against = compared.as_ref().map_or(String::new(), |c| c.line(k));
        emit(&format!(
            "  {:<10} at ({:.1}, {:.1}, {:.1}) mm in the left camera's frame, {:.0}% of its edges matched, image support {:.2}{against}",
            l.model,
            t.x,
            t.y,
            t.z,
            l.support_fraction * 100.0,
            l.image_support
        ))?;
    }
    if let Some(c) = &compared {
        emit(&c.summary())?;
    }
    Ok(())
}

/// A scene's truth as `marvin render` writes it: each object's model and pose in the left
/// camera's frame (the camera as built, where the measured cameras put the origin).
pub struct SceneTruth {
    path: PathBuf,
    objects: Vec<(u64, String, Isometry3<f64>)>,
}

/// A report is correct within this distance (mm) and turn (deg) of an object of its model, as
/// `marvin eval locate` has it.
const CORRECT_MM: f64 = 10.0;
const CORRECT_DEG: f64 = 5.0;

impl SceneTruth {
    pub fn load(path: &Path) -> anyhow::Result<SceneTruth> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        let scene: serde_json::Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
        let field = |v: &serde_json::Value, name: &str| -> anyhow::Result<mesh::pose::PoseRecord> {
            serde_json::from_value(v.clone()).with_context(|| format!("{}: field `{name}`", path.display()))
        };
        // The camera as built; an ideal scene's is the calibration's.
        let cam = match scene.pointer("/as_built/left/pinhole/world_from_cam") {
            Some(v) => field(v, "as_built.left.pinhole.world_from_cam")?,
            None => field(
                scene.pointer("/calibration/left/world_from_cam").unwrap_or(&serde_json::Value::Null),
                "calibration.left.world_from_cam",
            )?,
        };
        let cam_from_world = Isometry3::from(&cam).inverse();
        let Some(list) = scene["objects"].as_array() else {
            bail!("{}: no `objects` list (a scene.json of `marvin render` has one)", path.display());
        };
        let mut objects = Vec::new();
        for (k, o) in list.iter().enumerate() {
            let model = o["model"].as_str().with_context(|| format!("{}: objects[{k}].model", path.display()))?;
            let pose = field(&o["world_from_model"], &format!("objects[{k}].world_from_model"))?;
            objects.push((
                o["id"].as_u64().unwrap_or(k as u64),
                model.to_string(),
                cam_from_world * Isometry3::from(&pose),
            ));
        }
        Ok(SceneTruth { path: path.to_path_buf(), objects })
    }

    /// Each report against the nearest object of its model.
    pub fn compare(&self, library: &mesh::Library, located: &[vision::matcher::Located]) -> Compared {
        let reports = located
            .iter()
            .map(|l| {
                let symmetries = library.get(&l.model).map(marvin::eval::symmetries).unwrap_or_default();
                self.objects
                    .iter()
                    .filter(|(_, model, _)| *model == l.model)
                    .map(|(id, _, truth)| {
                        let (m, rad) = marvin::eval::pose_error(&l.cam_from_model, truth, &symmetries);
                        (*id, m * 1e3, rad.to_degrees())
                    })
                    .min_by(|a, b| a.1.total_cmp(&b.1))
            })
            .collect();
        Compared {
            file: self.path.display().to_string(),
            objects: self.objects.iter().map(|(id, m, _)| (*id, m.clone())).collect(),
            reports,
        }
    }
}

/// Reports against a truth file: per report the nearest object of its model (id, mm, deg).
pub struct Compared {
    file: String,
    objects: Vec<(u64, String)>,
    reports: Vec<Option<(u64, f64, f64)>>,
}

impl Compared {
    fn correct(r: &Option<(u64, f64, f64)>) -> bool {
        r.is_some_and(|(_, mm, deg)| mm <= CORRECT_MM && deg <= CORRECT_DEG)
    }

    /// The objects no correct report is of (some may be hidden from the cameras).
    fn not_located(&self) -> Vec<&(u64, String)> {
        self.objects
            .iter()
            .filter(|(id, _)| !self.reports.iter().any(|r| Self::correct(r) && r.is_some_and(|(o, _, _)| o == *id)))
            .collect()
    }

    fn line(&self, k: usize) -> String {
        match &self.reports[k] {
            Some((id, mm, deg)) => {
                let verdict = if Self::correct(&self.reports[k]) { "correct" } else { "FALSE" };
                format!("; object {id}: {mm:.1} mm, {deg:.1} deg off ({verdict})")
            }
            None => "; no object of this model (FALSE)".into(),
        }
    }

    fn summary(&self) -> String {
        let correct = self.reports.iter().filter(|r| Self::correct(r)).count();
        let missing: Vec<String> = self.not_located().iter().map(|(id, m)| format!("{m} (object {id})")).collect();
        format!(
            "against {}: {correct} of {} reports correct; not located ({} of {} objects, some perhaps hidden): {}",
            self.file,
            self.reports.len(),
            missing.len(),
            self.objects.len(),
            if missing.is_empty() { "none".into() } else { missing.join(", ") }
        )
    }

    fn to_json(&self) -> serde_json::Value {
        let reports: Vec<serde_json::Value> = self
            .reports
            .iter()
            .map(|r| match r {
                Some((id, mm, deg)) => serde_json::json!({ "object": id, "pos_err_mm": mm, "rot_err_deg": deg, "correct": Self::correct(r) }),
                None => serde_json::json!({ "object": null, "correct": false }),
            })
            .collect();
        let not_located: Vec<serde_json::Value> =
            self.not_located().iter().map(|(id, m)| serde_json::json!({ "object": id, "model": m })).collect();
        serde_json::json!({ "file": self.file, "reports": reports, "not_located": not_located })
    }
}
