//! `marvin eval pairs DIR --cameras FILE`: the matcher on stereo pairs imaged anywhere, as
//! `marvin locate --left --right` reads each one (the table from the pair's own 3D lines),
//! judged against each scene's truth and summed as `marvin eval locate` sums its scenes.
//!
//! `DIR` holds one folder per scene with `left.png`, `right.png` and the `scene.json` (and
//! `depth_left.png`, which tells the objects in view) of `marvin render`: the way to check
//! the pipeline on images another renderer, or a real rig, made of the same scenes.

use super::edges::load_grey_noting;
use super::eval_locate::{LocateScene, in_doubt, measure_at, summarise};
use super::locate_pair::{PairReading, load_cameras, read_pair};
use super::pair_truth::SceneTruth;
use anyhow::{Context, bail};
use marvin::engine::perception::{Pair, part_models};
use marvin::eval::batch::{Record, Shard, code_version};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Files each scene's folder holds.
const LEFT: &str = "left.png";
const RIGHT: &str = "right.png";
const TRUTH: &str = "scene.json";

pub fn run(dir: &Path, cameras: &Path, (doubt, json): (bool, bool)) -> anyhow::Result<()> {
    let folders = scene_folders(dir)?;
    let calib = load_cameras(cameras)?;
    let library = mesh::Library::load_default()?;
    let models = part_models(&library);
    let shared = json!({
        "world_name": dir.display().to_string(),
        "realism": "pairs read from files",
        "table": "each scene's own 3D lines",
        "cameras": cameras.display().to_string(),
    });
    let progress = super::output::Progress::new(folders.len() as u64, json);
    let mut records = Vec::new();
    let mut per_folder = Vec::new();
    let mut all_fates: std::collections::BTreeMap<String, usize> = std::collections::BTreeMap::new();
    for (k, folder) in folders.iter().enumerate() {
        let clock = Instant::now();
        let truth = SceneTruth::load(&folder.join(TRUTH))?;
        let pair = load_pair(folder, &calib)?;
        let match_clock = Instant::now();
        let PairReading { located, fe, top, .. } = read_pair(&pair, &models);
        let match_ms = match_clock.elapsed().as_secs_f64() * 1e3;
        let mut stats = truth.judge(&library, &located);
        let reading = Reading::of(&pair, &fe, top.as_ref());
        measure_missed(&mut stats.missed, &truth, &models, &reading);
        let in_doubt = doubt
            .then(|| in_doubt(&mut stats, &located, (&models, &reading.lines, &reading.params), &reading.evidence));
        let fates = truth.part_edgel_fates(&library, &fe, &calib);
        for (fate, n) in &fates {
            *all_fates.entry(fate.clone()).or_insert(0) += n;
        }
        let line = format!(
            "{}: located {}/{} objects in view, {} false of {} reports",
            folder.display(),
            stats.located,
            stats.eligible,
            stats.false_positives,
            stats.reports
        );
        per_folder.push(json!({
            "folder": folder.display().to_string(),
            "seed": truth.seed,
            "located": stats.located,
            "in_view": stats.eligible,
            "in_view_from_depth": truth.has_depth(),
            "false_reports": stats.false_positives,
            "reports": stats.reports,
        }));
        let scene = LocateScene { stats, unsettled: false, match_ms, table_found: None, in_doubt };
        records.push(Record {
            verb: "locate".into(),
            world: dir.display().to_string(),
            range: [0, folders.len() as u64 - 1],
            version: code_version(),
            // The missed parts and false reports name their scene by its seed where its
            // scene.json gives one, else by the folder's place in the sorted list.
            seed: truth.seed.unwrap_or(k as u64),
            shared: shared.clone(),
            scene: serde_json::to_value(scene)?,
        });
        progress.step(format!("{line} ({:.1} s)", clock.elapsed().as_secs_f64()));
    }
    progress.finish();
    let mut report = summarise(&records)?;
    report["seeds"] = json!(null);
    report["cameras"] = shared["cameras"].clone();
    report["scenes_read"] = json!(per_folder);
    report["part_edgels"] = fates_as_fractions(&all_fates);
    super::batch::print_report(report, Shard::ALL, json)
}

/// The folders under `dir` that hold a scene (a `left.png`), sorted by name.
fn scene_folders(dir: &Path) -> anyhow::Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("{}: cannot read the folder", dir.display()))?;
    let mut folders = Vec::new();
    for entry in entries {
        let path = entry.with_context(|| format!("{}: cannot read the folder", dir.display()))?.path();
        if path.join(LEFT).is_file() {
            for needed in [RIGHT, TRUTH] {
                if !path.join(needed).is_file() {
                    bail!("{}: has {LEFT} but no {needed}", path.display());
                }
            }
            folders.push(path);
        }
    }
    if folders.is_empty() {
        bail!("{}: no folder in it holds a scene ({LEFT}, {RIGHT} and {TRUTH} of `marvin render`)", dir.display());
    }
    folders.sort();
    Ok(folders)
}

/// A folder's two images, checked against each other and against the cameras.
fn load_pair(folder: &Path, calib: &mesh::StereoCalibration) -> anyhow::Result<Pair> {
    let mut notes = Vec::new();
    let left = load_grey_noting(&folder.join(LEFT), &mut notes)?;
    let right = load_grey_noting(&folder.join(RIGHT), &mut notes)?;
    for (name, img) in [(LEFT, &left), (RIGHT, &right)] {
        if (img.width, img.height) != (calib.left.width as usize, calib.left.height as usize) {
            bail!(
                "{}: {}x{}, but the cameras are for {}x{} images",
                folder.join(name).display(),
                img.width,
                img.height,
                calib.left.width,
                calib.left.height
            );
        }
    }
    for note in notes {
        eprintln!("note: {note}");
    }
    Ok(Pair { left, right, calib: calib.clone() })
}

/// What the matcher read a pair with: the left image's evidence (the right's within it), the
/// 3D lines and the parameters with the table the pair's own lines gave.
struct Reading<'e> {
    evidence: vision::matcher::verify::ImageEvidence<'e>,
    lines: Vec<vision::matcher::Seg>,
    params: vision::matcher::MatchParams,
}

impl<'e> Reading<'e> {
    fn of(
        pair: &'e Pair,
        fe: &'e vision::front_end::FrontEnd,
        top: Option<&vision::front_end::table_top::TableTop>,
    ) -> Reading<'e> {
        Reading {
            evidence: vision::matcher::verify::ImageEvidence::of_pair(&pair.calib, fe),
            lines: marvin::engine::perception::scene_lines(fe),
            params: marvin::engine::perception::part_params(top.map(|t| t.table.cam_from_table()).as_ref()),
        }
    }
}

/// Each missed object measured at its true pose as the matcher measures its readings (`eval
/// locate`'s `at_truth`): whether the evidence was there, judged afterwards.
fn measure_missed(
    missed: &mut [marvin::eval::Missed],
    truth: &SceneTruth,
    models: &[vision::matcher::MatcherModel],
    reading: &Reading,
) {
    for m in missed {
        let Some(model) = models.iter().find(|x| x.name == m.model) else { continue };
        let at = measure_at(model, &truth.cam_from_model(m.id), (&reading.lines, &reading.params), &reading.evidence);
        m.at_truth = Some(at);
    }
}

/// Edgel fates as fractions of all counted, with the count.
fn fates_as_fractions(fates: &std::collections::BTreeMap<String, usize>) -> serde_json::Value {
    let total: usize = fates.values().sum();
    let mut out: serde_json::Map<String, serde_json::Value> =
        fates.iter().map(|(k, n)| (k.clone(), json!(*n as f64 / total.max(1) as f64))).collect();
    out.insert("counted".into(), json!(total));
    serde_json::Value::Object(out)
}
