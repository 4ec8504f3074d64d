//! `marvin eval locate`: the matcher over seeded scenes against the truth, with the table placed
//! as `marvin run` places it ([`super::table`]); batched like `eval run` (`--shard`, `--out`,
//! `--resume`, `--jobs`, and `marvin eval merge` of the records).

use super::batch::{Batch, Runner, print_report};
use super::scene::{eval_cameras, matcher_models, run_pipeline};
use anyhow::Context;
use marvin::eval::batch::Record;
use marvin::eval::{LocateStats, locate_stats, quantile, symmetries};
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Where vision's cameras and the table's place come from, and Canny's settings.
pub struct Sources {
    pub cameras: Option<PathBuf>,
    pub hand_eye: Option<PathBuf>,
    /// Each scene's table from its own 3D lines (`front_end::table_top`), not the hand-eye's.
    pub table_from_images: bool,
    pub canny: vision::CannyParams,
    /// Judge which reports are in doubt ([`LocateScene::in_doubt`]).
    pub doubt: bool,
}

/// What `eval locate` keeps of one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LocateScene {
    pub stats: LocateStats,
    pub unsettled: bool,
    /// Wall time of the matcher: it differs from machine to machine and run to run.
    pub match_ms: f64,
    /// With the table found in the scene's own lines: how far the true table's top at the
    /// workspace's centre lies from the top found (mm, signed: above it positive) and the angle
    /// between their normals (deg); `None` where no top was found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table_found: Option<TableFound>,
    /// With `--doubt`: how many right reports, and how many false ones, a turn of the part
    /// fits as well (`vision::matcher::polish::doubt::TurnedAlike::fits_as_well`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub in_doubt: Option<[usize; 2]>,
}

/// See [`LocateScene::table_found`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TableFound {
    pub error: Option<[f64; 2]>,
}

/// `marvin eval locate`.
pub fn eval(b: &Batch, sources: &Sources) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&b.world)?;
    let runner = Runner::open(b, "locate")?;
    let imaging = sim::imaging::Imaging::new(&scn.world);
    let cams = eval_cameras(&imaging, sources.cameras.as_deref())?;
    let calib = cams.vision.clone();
    let table = if sources.table_from_images {
        super::table::TableEstimate { cam_from_table: None, source: "each scene's own 3D lines".into() }
    } else {
        super::table::cam_from_table(&b.world, &scn, &calib, sources.hand_eye.as_deref(), b.seed, b.json)?
    };
    let models = matcher_models(&scn.library, None);
    let symmetry: BTreeMap<String, Vec<Isometry3<f64>>> =
        scn.library.models.values().map(|m| (m.name.clone(), symmetries(m))).collect();
    let params = marvin::engine::perception::part_params(table.cam_from_table.as_ref());
    let shared = json!({ "world_name": scn.world.name, "realism": imaging.preset, "table": table.source });
    let scene = |s: u64| {
        let p = run_pipeline(&scn, &imaging, s, &sources.canny, &cams, table.cam_from_table.as_ref());
        let lines: Vec<vision::matcher::Seg> =
            p.front_end.lines3d.iter().map(|l| vision::matcher::Seg::new(l.start(), l.end())).collect();
        let clock = std::time::Instant::now();
        let evidence = vision::matcher::verify::ImageEvidence::of_pair(&calib, &p.front_end);
        let (located, table_found) = if sources.table_from_images {
            let top = vision::front_end::table_top::find(&p.front_end.lines3d);
            let params = vision::matcher::MatchParams { table: top.as_ref().map(|t| t.table), ..params };
            // The true top (the world's z = 0) in vision's frame, judged after the matcher ran.
            let cam_from_world = calib.left.cam_from_world();
            let error = top.map(|t| {
                let centre = cam_from_world * nalgebra::Point3::origin();
                let up = cam_from_world * nalgebra::Vector3::z();
                [t.table.height_of(&centre) * 1e3, nalgebra::Vector3::from(t.table.up).angle(&up).to_degrees()]
            });
            (vision::matcher::locate_all(&models, &lines, &params, Some(&evidence)), Some(TableFound { error }))
        } else {
            (vision::matcher::locate_all(&models, &lines, &params, Some(&evidence)), None)
        };
        let match_ms = clock.elapsed().as_secs_f64() * 1e3;
        let mut stats = locate_stats(&located, &p.scene.objects, &scn.library, &p.cams, Some(&p.left.depth), &symmetry);
        measure_at_truth(&mut stats.missed, &p.scene, &calib, (&models, &lines, &params), &evidence);
        measure_as_reported(&mut stats.false_reports, &located, (&models, &lines, &params), &evidence);
        let in_doubt = sources.doubt.then(|| in_doubt(&mut stats, &located, (&models, &lines, &params), &evidence));
        let line = format!(
            "located {}/{} visible objects, {} false of {} reports",
            stats.located, stats.eligible, stats.false_positives, stats.reports
        );
        Ok((serde_json::to_value(LocateScene { stats, unsettled: !p.settled, match_ms, table_found, in_doubt })?, line))
    };
    let records = runner.run(&shared, &scene)?;
    print_report(summarise(&records)?, b.shard, b.json)
}

/// How many of the right reports, and of the false ones, are in doubt: a turn of the part fits
/// them as well in both images. Each false report is marked.
pub(super) fn in_doubt(
    stats: &mut LocateStats,
    located: &[vision::matcher::Located],
    (models, lines, params): (&[vision::matcher::MatcherModel], &[vision::matcher::Seg], &vision::matcher::MatchParams),
    evidence: &vision::matcher::verify::ImageEvidence,
) -> [usize; 2] {
    let all = vec![true; located.len()];
    let alike = vision::matcher::polish::doubt::turned_alike(models, (lines, params), evidence, located, &all);
    let doubted = |i: usize| alike[i].is_some();
    for f in &mut stats.false_reports {
        f.in_doubt = Some(doubted(f.index));
    }
    let false_ones: Vec<usize> = stats.false_reports.iter().map(|f| f.index).collect();
    let (wrong, right): (Vec<usize>, Vec<usize>) =
        (0..located.len()).filter(|&i| doubted(i)).partition(|i| false_ones.contains(i));
    [right.len(), wrong.len()]
}

/// Each missed object's true pose (in the frame of the camera vision was given) measured as
/// the matcher measures its readings: whether the evidence was there, judged afterwards.
fn measure_at_truth(
    missed: &mut [marvin::eval::Missed],
    scene: &sim::Scene,
    calib: &mesh::StereoCalibration,
    (models, lines, params): (&[vision::matcher::MatcherModel], &[vision::matcher::Seg], &vision::matcher::MatchParams),
    evidence: &vision::matcher::verify::ImageEvidence,
) {
    for m in missed {
        let Some(model) = models.iter().find(|x| x.name == m.model) else { continue };
        let pose = calib.left.cam_from_world() * scene.objects[m.id].world_from_model;
        m.at_truth = Some(measure_at(model, &pose, (lines, params), evidence));
    }
}

/// Each false report measured at its own pose as [`measure_at_truth`] measures a missed object.
fn measure_as_reported(
    false_reports: &mut [marvin::eval::FalseReport],
    located: &[vision::matcher::Located],
    (models, lines, params): (&[vision::matcher::MatcherModel], &[vision::matcher::Seg], &vision::matcher::MatchParams),
    evidence: &vision::matcher::verify::ImageEvidence,
) {
    for f in false_reports {
        let Some(model) = models.iter().find(|x| x.name == f.model) else { continue };
        f.as_reported = Some(measure_at(model, &located[f.index].cam_from_model, (lines, params), evidence));
    }
}

/// The matcher's measures of `model` at `pose` (`cam`).
pub(super) fn measure_at(
    model: &vision::matcher::MatcherModel,
    pose: &Isometry3<f64>,
    (lines, params): (&[vision::matcher::Seg], &vision::matcher::MatchParams),
    evidence: &vision::matcher::verify::ImageEvidence,
) -> marvin::eval::AtTruth {
    let (support_fraction, seen) = vision::matcher::support_at(model, pose, lines, params);
    let image_support = vision::matcher::verify::image_support(model, pose, evidence);
    let image_support_right = evidence
        .right
        .as_ref()
        .map(|r| vision::matcher::verify::image_support(model, &(r.right_from_cam * pose), &r.ev));
    marvin::eval::AtTruth { support_fraction, lines: seen, image_support, image_support_right }
}

/// The summary of `eval locate` records (sorted by seed), as one process over them prints it.
/// Everything but `match_ms_median` (a wall time) is a function of the records' scenes alone.
pub fn summarise(records: &[Record]) -> anyhow::Result<Value> {
    let first = records.first().context("no scenes to summarise")?;
    let mut total = LocateStats::default();
    let (mut match_ms, mut unsettled, mut false_reports, mut missed) = (Vec::new(), 0, Vec::new(), Vec::new());
    let mut tables: Vec<Option<[f64; 2]>> = Vec::new();
    let mut doubted: Option<[usize; 2]> = None;
    for r in records {
        let scene: LocateScene = serde_json::from_value(r.scene.clone())
            .with_context(|| format!("seed {}: not an `eval locate` scene", r.seed))?;
        false_reports.extend(scene.stats.false_reports.iter().map(|f| json!({ "seed": r.seed, "report": f })));
        missed.extend(scene.stats.missed.iter().map(|m| json!({ "seed": r.seed, "object": m })));
        match_ms.push(scene.match_ms);
        unsettled += usize::from(scene.unsettled);
        total.add(&scene.stats);
        tables.extend(scene.table_found.map(|t| t.error));
        if let Some([right, wrong]) = scene.in_doubt {
            let d = doubted.get_or_insert([0, 0]);
            (d[0], d[1]) = (d[0] + right, d[1] + wrong);
        }
    }
    let located_by_model: BTreeMap<String, f64> =
        total.by_model.iter().map(|(m, [e, l])| (m.clone(), *l as f64 / (*e).max(1) as f64)).collect();
    let mut report = json!({
        "world": first.shared["world_name"],
        "realism": first.shared["realism"],
        "seeds": first.range,
        "scenes": records.len(),
        "table": first.shared["table"],
        "located_fraction": total.located as f64 / total.eligible.max(1) as f64,
        "pos_err_mm_median": quantile(&total.pos_err_mm, 0.5),
        "pos_err_mm_p90": quantile(&total.pos_err_mm, 0.9),
        "rot_err_deg_median": quantile(&total.rot_err_deg, 0.5),
        "false_positive_fraction": total.false_positives as f64 / total.reports.max(1) as f64,
        "match_ms_median": quantile(&match_ms, 0.5),
        "unsettled_scenes": unsettled,
        "located_by_model": located_by_model,
        "false_reports": false_reports,
        "missed": missed,
        "version": first.version,
    });
    if let Some([right, wrong]) = doubted {
        report["in_doubt"] = json!({ "right_reports": right, "false_reports": wrong });
    }
    if !tables.is_empty() {
        let found: Vec<[f64; 2]> = tables.iter().flatten().copied().collect();
        let heights: Vec<f64> = found.iter().map(|e| e[0].abs()).collect();
        let angles: Vec<f64> = found.iter().map(|e| e[1]).collect();
        report["table_from_images"] = json!({
            "found_fraction": found.len() as f64 / tables.len() as f64,
            "height_err_mm_median": quantile(&heights, 0.5),
            "height_err_mm_max": heights.iter().copied().fold(0.0, f64::max),
            "angle_deg_median": quantile(&angles, 0.5),
        });
    }
    marvin::eval::add_intervals(
        &mut report,
        &[
            ("located_fraction", total.located, total.eligible),
            ("false_positive_fraction", total.false_positives, total.reports),
        ],
    );
    Ok(report)
}
