//! `marvin eval vision`: the front end over seeded scenes against the truth (disparities, 3D
//! lines, what became of each left edgel); batched like `eval run` (`--shard`, `--out`,
//! `--resume`, `--jobs`, and `marvin eval merge` of the records).

use super::batch::{Batch, Runner, print_report};
use super::scene::{canny_params, eval_cameras};
use anyhow::Context;
use marvin::eval::batch::Record;
use marvin::eval::truth::TruthScene;
use marvin::eval::{ArmMask, DisparityStats, LineStats, disparity_stats, edgel_fates, line_stats};
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// How the front end sees: through which cameras, deblurred or not, in how many slices.
pub struct Sources {
    pub cameras: Option<PathBuf>,
    /// Places the table (the front end then searches nothing under it).
    pub hand_eye: Option<PathBuf>,
    pub deblur: bool,
    pub slices: usize,
}

/// What `eval vision` keeps of one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VisionScene {
    pub disparity: DisparityStats,
    /// Matches on the arm, counted apart.
    pub on_arm: DisparityStats,
    pub lines: LineStats,
    /// What became of the left edgels with a true disparity, counted.
    pub fates: BTreeMap<String, usize>,
    pub unsettled: bool,
    /// Wall time of each stage: it differs from machine to machine and run to run.
    pub timings_ms: Vec<(String, f64)>,
}

/// `marvin eval vision`.
pub fn eval(b: &Batch, sources: &Sources) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&b.world)?;
    let runner = Runner::open(b, "vision")?;
    let imaging = sim::imaging::Imaging::new(&scn.world);
    // What vision is given: the world file's cameras (the truth only in the ideal preset), or
    // measured ones.
    let cams = eval_cameras(&imaging, sources.cameras.as_deref())?;
    let cameras = sources.cameras.as_ref().map_or("the world file's".to_string(), |p| p.display().to_string());
    let (cam_from_table, table) = match &sources.hand_eye {
        Some(file) => {
            let t = super::table::cam_from_table(&b.world, &scn, &cams.vision, Some(file), b.seed, b.json)?;
            (t.cam_from_table, t.source)
        }
        None => (None, "none: no --hand-eye".to_string()),
    };
    let workspace = marvin::engine::perception::workspace(cam_from_table.as_ref());
    let shared = json!({
        "world_name": scn.world.name, "realism": imaging.preset, "cameras": cameras,
        "deblur": sources.deblur, "slices": sources.slices, "table": table,
    });
    let params = canny_params(sources.deblur);
    let scene = |s: u64| {
        let (scene, settled) = super::output::settle(&scn, s);
        let (l, r) = imaging.render_stereo(&scene.render_scene(&scn.library, &imaging), s);
        let left = vision::GreyImage::new(l.width, l.height, l.image.clone()).expect("a rendered frame is whole");
        let right = vision::GreyImage::new(r.width, r.height, r.image.clone()).expect("a rendered frame is whole");
        let mut fe = if sources.slices > 1 {
            vision::front_end::slices::run_sliced(&left, &right, &cams.vision, &workspace, &params, sources.slices)
        } else {
            marvin::front_end::run(&left, &right, &cams.vision, &workspace, &params)
        };
        // Without a hand-eye calibration the table's top is taken from the 3D lines, as
        // `marvin locate --left --right` takes it, to set the shadows and texture apart.
        if workspace.table.is_none()
            && let Some(top) = vision::front_end::table_top::find(&fe.lines3d)
        {
            fe.set_apart_soft_lines(&top.table);
        }
        let truth = TruthScene::new(scene.world_meshes(&scn.library).map(|(_, m)| m));
        let arm = ArmMask::from_ids(l.width, l.height, &l.ids);
        let (disparity, on_arm) = disparity_stats(&fe, &truth, &cams, &arm);
        let lines = line_stats(&fe, &scene, &scn.library, &cams, &l.depth, &arm);
        let line = format!(
            "{} matches, {:.3} within 0.5 px, {:.3} wrong; {} 3D lines, ends {:.2} mm median, coverage {:.2}",
            disparity.evaluated,
            disparity.within_fraction(),
            disparity.wrong_fraction(),
            lines.endpoint_err_mm.len() / 2,
            lines.endpoint_quantile(0.5),
            lines.coverage()
        );
        let fates = edgel_fates(&fe, &truth, &cams, &|e| arm.covers(e.x as f64, e.y as f64));
        let timings_ms = fe.timings_ms.iter().map(|(k, ms)| (k.to_string(), *ms)).collect();
        let figures = VisionScene { disparity, on_arm, lines, fates, unsettled: !settled, timings_ms };
        Ok((serde_json::to_value(figures)?, line))
    };
    let records = runner.run(&shared, &scene)?;
    print_report(summarise(&records)?, b.shard, b.json)
}

/// The summary of `eval vision` records (sorted by seed), as one process over them prints it.
/// Everything but `timings_ms` (wall times) is a function of the records' scenes alone.
pub fn summarise(records: &[Record]) -> anyhow::Result<Value> {
    let first = records.first().context("no scenes to summarise")?;
    let (mut total, mut on_arm, mut lines) =
        (DisparityStats::default(), DisparityStats::default(), LineStats::default());
    let mut fates: BTreeMap<String, usize> = BTreeMap::new();
    let mut timings: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    let mut unsettled = 0;
    for r in records {
        let scene: VisionScene = serde_json::from_value(r.scene.clone())
            .with_context(|| format!("seed {}: not an `eval vision` scene", r.seed))?;
        total.add(&scene.disparity);
        on_arm.add(&scene.on_arm);
        lines.add(&scene.lines);
        for (fate, n) in scene.fates {
            *fates.entry(fate).or_insert(0) += n;
        }
        for (stage, ms) in scene.timings_ms {
            timings.entry(stage).or_default().push(ms);
        }
        unsettled += usize::from(scene.unsettled);
    }
    let medians: BTreeMap<String, f64> = timings
        .into_iter()
        .map(|(k, mut v)| {
            v.sort_by(f64::total_cmp);
            (k, v[v.len() / 2])
        })
        .collect();
    let scenes = records.len() as f64;
    let mut report = json!({
        "world": first.shared["world_name"],
        "realism": first.shared["realism"],
        "cameras": first.shared["cameras"],
        "table": first.shared.get("table").cloned().unwrap_or_else(|| json!("none")),
        "seeds": first.range,
        "scenes": records.len(),
        "disparity_within_0_5px": total.within_fraction(),
        "wrong_matches": total.wrong_fraction(),
        "matches_per_scene": total.evaluated as f64 / scenes,
        "endpoint_err_mm_median": lines.endpoint_quantile(0.5),
        "endpoint_err_mm_p90": lines.endpoint_quantile(0.9),
        "coverage": lines.coverage(),
        "lines3d_per_scene": lines.endpoint_err_mm.len() as f64 / 2.0 / scenes,
        "lines3d_off_edges": lines.off_edge_lines as f64 / (lines.endpoint_err_mm.len() as f64 / 2.0).max(1.0),
        "lines3d_off_edges_on_table": lines.off_edge_on_table as f64 / (lines.endpoint_err_mm.len() as f64 / 2.0).max(1.0),
        "lines3d_on_table": lines.on_table_lines as f64 / (lines.endpoint_err_mm.len() as f64 / 2.0).max(1.0),
        "set_apart": {
            "per_scene": lines.set_apart_lines as f64 / scenes,
            "off_edges": lines.set_apart_off_edges as f64 / (lines.set_apart_lines as f64).max(1.0),
            "of_off_edges_on_table": lines.set_apart_off_edges as f64
                / ((lines.set_apart_off_edges + lines.off_edge_on_table) as f64).max(1.0),
        },
        "arm": {
            "matches_per_scene": on_arm.evaluated as f64 / scenes,
            "disparity_within_0_5px": on_arm.within_fraction(),
            "wrong_matches": on_arm.wrong_fraction(),
            "lines3d_per_scene": lines.arm_lines as f64 / scenes,
        },
        "left_edgels": fractions_of(&fates),
        "timings_ms": medians,
        "unsettled_scenes": unsettled,
        "version": first.version,
    });
    marvin::eval::add_intervals(
        &mut report,
        &[
            ("disparity_within_0_5px", total.within_0_5px, total.evaluated),
            ("wrong_matches", total.wrong, total.evaluated),
            ("arm.disparity_within_0_5px", on_arm.within_0_5px, on_arm.evaluated),
            ("arm.wrong_matches", on_arm.wrong, on_arm.evaluated),
        ],
    );
    Ok(report)
}

/// Each count as a fraction of their total.
fn fractions_of(counts: &BTreeMap<String, usize>) -> BTreeMap<String, f64> {
    let total = counts.values().sum::<usize>().max(1) as f64;
    counts.iter().map(|(k, &n)| (k.clone(), n as f64 / total)).collect()
}
