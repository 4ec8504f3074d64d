//! `marvin locate --left L --right R --cameras FILE`: the front end and the matcher on any
//! stereo pair, from any cameras: what was found (model, pose and grasp in the left camera's
//! frame, support); compared with a truth file (`--truth`, a scene.json of `marvin render`)
//! only when one is given, after the matcher has run.

use super::edges::load_grey_noting;
use super::output::emit;
use super::pair_truth::SceneTruth;
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
    /// A scene.json of `marvin render`, to compare with.
    pub truth: Option<PathBuf>,
}

/// The cameras of a calibration file: the project's cameras.json, or a scene.json.
pub fn load_cameras(path: &Path) -> anyhow::Result<mesh::StereoCalibration> {
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
    let PairReading { located, fe, top, notes: found } = read_pair(&pair, &models);
    notes.extend(found);
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
    let compared = truth.as_ref().map(|t| Compared::of(t, &library, &located));
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

/// What the front end and the matcher made of a pair, and notes on how.
pub struct PairReading {
    pub located: Vec<vision::matcher::Located>,
    pub fe: vision::front_end::FrontEnd,
    pub top: Option<vision::front_end::table_top::TableTop>,
    pub notes: Vec<String>,
}

/// The front end and the matcher on a pair from any cameras. No cell layout says where the
/// table is in these cameras' frame: the matcher takes it from the scene's own 3D lines (the
/// front end searched without it), and the lines on it with soft edges (shadows, texture) are
/// set apart.
pub fn read_pair(pair: &Pair, models: &[vision::matcher::MatcherModel]) -> PairReading {
    let mut fe = front_end(pair, None);
    let top = vision::front_end::table_top::find(&fe.lines3d);
    let mut notes = vec![match &top {
        Some(t) => format!(
            "the table's top found on {} 3D lines ({:.0} mm of them), {:.1} mm below the left camera",
            t.lines.len(),
            t.length_m * 1e3,
            t.table.camera_height_m * 1e3
        ),
        None => "no table's top found in the 3D lines: the matcher looks without one".to_string(),
    }];
    if let Some(t) = &top {
        fe.set_apart_soft_lines(&t.table);
        notes.push(format!("{} 3D lines on the table's top set apart as shadows or texture", fe.set_apart.len()));
    }
    let located = locate_parts(models, pair, &fe, top.as_ref().map(|t| t.table.cam_from_table()).as_ref());
    PairReading { located, fe, top, notes }
}

/// Reports against a truth file: counted as `eval locate` counts them, and each report's
/// nearest object of its model (id, mm, deg).
struct Compared {
    file: String,
    stats: marvin::eval::LocateStats,
    nearest: Vec<Option<(u32, f64, f64)>>,
    /// The ids of the objects in view not located.
    missed: Vec<(u32, String)>,
    in_view_from_depth: bool,
}

impl Compared {
    fn of(truth: &SceneTruth, library: &mesh::Library, located: &[vision::matcher::Located]) -> Compared {
        let stats = truth.judge(library, located);
        let missed = stats.missed.iter().map(|m| (truth.id(m.id), m.model.clone())).collect();
        Compared {
            file: truth.path.display().to_string(),
            nearest: truth.nearest(library, located),
            missed,
            in_view_from_depth: truth.has_depth(),
            stats,
        }
    }

    fn correct(&self, k: usize) -> bool {
        !self.stats.false_reports.iter().any(|f| f.index == k)
    }

    fn line(&self, k: usize) -> String {
        let verdict = if self.correct(k) { "correct" } else { "FALSE" };
        match &self.nearest[k] {
            Some((id, mm, deg)) => format!("; object {id}: {mm:.1} mm, {deg:.1} deg off ({verdict})"),
            None => "; no object of this model (FALSE)".into(),
        }
    }

    fn in_view(&self) -> &'static str {
        if self.in_view_from_depth {
            "in view (30% of their edges, by depth_left.png)"
        } else {
            "(no depth_left.png beside it: all counted as in view)"
        }
    }

    fn summary(&self) -> String {
        let s = &self.stats;
        let missing: Vec<String> = self.missed.iter().map(|(id, m)| format!("{m} (object {id})")).collect();
        format!(
            "against {}: {} of {} reports correct, {} false; located {} of {} objects {}; not located: {}",
            self.file,
            s.reports - s.false_positives,
            s.reports,
            s.false_positives,
            s.located,
            s.eligible,
            self.in_view(),
            if missing.is_empty() { "none".into() } else { missing.join(", ") }
        )
    }

    fn to_json(&self) -> serde_json::Value {
        let reports: Vec<serde_json::Value> = (0..self.nearest.len())
            .map(|k| match &self.nearest[k] {
                Some((id, mm, deg)) => serde_json::json!({ "object": id, "pos_err_mm": mm, "rot_err_deg": deg, "correct": self.correct(k) }),
                None => serde_json::json!({ "object": null, "correct": false }),
            })
            .collect();
        let not_located: Vec<serde_json::Value> =
            self.missed.iter().map(|(id, m)| serde_json::json!({ "object": id, "model": m })).collect();
        let s = &self.stats;
        serde_json::json!({
            "file": self.file,
            "reports": reports,
            "not_located": not_located,
            "located": s.located,
            "in_view": s.eligible,
            "in_view_from_depth": self.in_view_from_depth,
            "false_reports": s.false_positives,
        })
    }
}
