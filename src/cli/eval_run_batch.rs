//! `marvin eval run` over a seed range: one camera calibration and one hand-eye calibration
//! (on the range's first scene, or from files) shared by every scene; the scenes of `--shard`,
//! `--jobs` at a time, each recorded as it ends (`--out`, `--resume`); and the summary, which
//! `marvin eval merge` makes the same way from the records of every shard.

use super::batch::{Batch, Runner, print_report};
use super::calibrate::Cell;
use super::cameras::cameras;
use super::eval_run::{Judge, calibration_error};
use super::session::{HandEye, failures, hand_eye, outcome_name, run_once};
use anyhow::Context;
use marvin::engine::run::{Cycle, RunConfig, Stop};
use marvin::eval::batch::Record;
use marvin::protocol::PickOutcomeKind;
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Where the calibration every scene shares comes from: files, or (neither given) calibrated on
/// the range's first scene.
pub struct Shared {
    pub cameras: Option<PathBuf>,
    pub hand_eye: Option<PathBuf>,
}

/// What `eval run` keeps of one scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunScene {
    pub on_table: usize,
    pub cleared: usize,
    pub picks: usize,
    pub placed: usize,
    pub first_attempts: usize,
    pub first_placed: usize,
    pub wrong_picks: Vec<Value>,
    pub cycles: usize,
    pub failures: BTreeMap<String, usize>,
    /// Each pick that failed: seed, cycle, model chosen, outcome and the server's detail (where
    /// the part came to rest and why that is not in the bin), so a drop can be found again.
    #[serde(default)]
    pub failed_picks: Vec<Value>,
    pub stopped_by: String,
    /// Picks planned with the neighbours left out (every part blocked by another), and of
    /// those placed.
    #[serde(default)]
    pub pushing_picks: usize,
    #[serde(default)]
    pub pushing_placed: usize,
    pub unsettled: bool,
    /// Wall times: they differ from machine to machine and run to run.
    pub cycle_s: Vec<f64>,
    pub vision_ms: Vec<f64>,
}

/// `marvin eval run`.
pub fn eval(b: &Batch, given: &Shared) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&b.world)?;
    let runner = Runner::open(b, "run")?;
    let (cameras, cam_from_base, shared) = shared_calibration(b, given, &scn)?;
    let scene = |s: u64| {
        let scene = run_scene(&b.world, &scn, s, &cameras, &cam_from_base)?;
        let mut line = format!(
            "{} of {} cleared, {} of {} picks placed, stopped by {}",
            scene.cleared, scene.on_table, scene.placed, scene.picks, scene.stopped_by
        );
        for f in &scene.failed_picks {
            line += &format!(
                "; cycle {} {}: {}",
                f["cycle"],
                f["model"].as_str().unwrap_or("?"),
                f["outcome"].as_str().unwrap_or("?")
            );
        }
        Ok((serde_json::to_value(&scene)?, line))
    };
    let records = runner.run(&shared, &scene)?;
    print_report(summarise(&records)?, b.shard, b.json)
}

/// The cameras and the hand-eye transform every scene shares, from files or calibrated on the
/// range's first scene (whatever the shard: every shard makes the same calibration), and what
/// the records say of them.
fn shared_calibration(
    b: &Batch,
    given: &Shared,
    scn: &sim::Scenario,
) -> anyhow::Result<(mesh::StereoCalibration, Isometry3<f64>, Value)> {
    let measured = given.cameras.as_deref().map(super::calibrate::load_cameras).transpose()?;
    let cell = Cell::start(&b.world, b.seed, None)?;
    let (mut client, hello) = cell.connect_greeted()?;
    let (cameras, _) = cameras(&mut client, &hello, &scn.library, measured.as_ref(), b.seed, true, false)?;
    let source = match &given.hand_eye {
        Some(f) => HandEye::File(f.clone()),
        None => HandEye::Calibrate,
    };
    let (cam_from_base, _) = hand_eye(&mut client, &scn.library, &source, b.seed, true, &cameras)?;
    let (mm, deg) = calibration_error(cell.local().context("a local server")?, &cam_from_base)?;
    client.bye()?;
    cell.stop()?;
    let how = match (&given.cameras, &given.hand_eye) {
        (None, None) => format!("one, on seed {}'s scene, shared by all scenes", b.seed),
        _ => "from files, shared by all scenes".into(),
    };
    let shared = json!({
        "world_name": scn.world.name,
        "calibration": how,
        "calibration_error": { "translation_mm": mm, "rotation_deg": deg },
    });
    Ok((cameras, cam_from_base, shared))
}

/// One scene's run, judged.
fn run_scene(
    world: &Path,
    scn: &sim::Scenario,
    s: u64,
    cameras: &mesh::StereoCalibration,
    cam_from_base: &Isometry3<f64>,
) -> anyhow::Result<RunScene> {
    let cell = Cell::start(world, s, None)?;
    let known = HandEye::Known(*cam_from_base);
    let mut judge = Judge::new(cell.local(), &scn.library);
    let config = RunConfig { cameras: Some(cameras.clone()), ..RunConfig::default() };
    let r = run_once(&cell, scn, s, &known, &config, true, &mut |_| String::new(), None, None, &mut judge)?;
    let truth = judge.verdict().truth.context("a local server gives the truth")?;
    cell.stop()?;
    // A pick succeeds when the server placed the part it aimed at and that part is of the
    // model chosen, where vision saw it (a wrong pick the server placed is no success).
    let tried: Vec<&Cycle> = r.cycles.iter().filter(|c| c.chosen.is_some()).collect();
    let success: Vec<bool> = tried
        .iter()
        .zip(&truth.picks)
        .map(|(c, judged)| outcome_name(c) == "placed" && judged.target().is_some())
        .collect();
    let firsts = truth.first_attempts();
    let wrong_picks = truth
        .wrong_picks()
        .map(|p| {
            json!({ "seed": s, "cycle": p.cycle + 1, "model": p.model, "support": p.support_fraction,
                    "image_support": p.image_support,
                    "outcome": r.cycles.get(p.cycle).map(outcome_name), "nearest_of_model_mm": p.nearest.map(|(_, mm, _)| mm),
                    "nearest_of_model_deg": p.nearest.map(|(_, _, deg)| deg),
                    "nearest_object": p.nearest_any.as_ref().map(|(id, model, mm)| json!({ "id": id, "model": model, "mm": mm })) })
        })
        .collect();
    let stopped_by = match r.stop {
        Stop::NothingLocated => "nothing_located",
        Stop::NothingPickable => "nothing_pickable",
        Stop::MaxCycles => "max_cycles",
    };
    Ok(RunScene {
        on_table: truth.on_table_at_start,
        cleared: truth.in_bin_at_end,
        picks: tried.len(),
        placed: success.iter().filter(|s| **s).count(),
        first_attempts: firsts.iter().filter(|f| **f).count(),
        first_placed: success.iter().zip(&firsts).filter(|(ok, first)| **ok && **first).count(),
        wrong_picks,
        cycles: r.cycles.len(),
        failures: failures(&r.cycles),
        failed_picks: failed_picks(s, &r.cycles),
        stopped_by: stopped_by.into(),
        pushing_picks: r.cycles.iter().filter(|c| c.pushing_neighbours).count(),
        pushing_placed: r
            .cycles
            .iter()
            .filter(|c| {
                c.pushing_neighbours && matches!(&c.outcome, Some(Ok(p)) if p.outcome == Some(PickOutcomeKind::Placed))
            })
            .count(),
        unsettled: truth.unsettled.is_some(),
        cycle_s: r.cycles.iter().map(|c| c.cycle_s).collect(),
        vision_ms: r.cycles.iter().map(Cycle::vision_ms).collect(),
    })
}

/// Every pick of `cycles` that was tried and not placed, named for finding it again (`marvin
/// run --seed`).
fn failed_picks(seed: u64, cycles: &[Cycle]) -> Vec<Value> {
    cycles
        .iter()
        .enumerate()
        .filter_map(|(k, c)| Some((k, c, c.chosen_model()?)))
        .filter(|(_, c, _)| outcome_name(c) != "placed")
        .map(|(k, c, model)| {
            let reply = c.reply();
            let (detail, grip) = (reply.and_then(|r| r.detail.clone()), reply.and_then(|r| r.grip_past_com_mm));
            json!({ "seed": seed, "cycle": k + 1, "model": model, "outcome": outcome_name(c), "detail": detail, "grip_past_com_mm": grip })
        })
        .collect()
}

/// The summary of `eval run` records (sorted by seed), as one process over them prints it.
/// Everything but `cycle_s_mean` and `vision_cycle_ms_median` (wall times) is a function of the
/// records' scenes alone.
pub fn summarise(records: &[Record]) -> anyhow::Result<Value> {
    let first = records.first().context("no scenes to summarise")?;
    let scenes: Vec<RunScene> = records
        .iter()
        .map(|r| {
            serde_json::from_value(r.scene.clone()).with_context(|| format!("seed {}: not an `eval run` scene", r.seed))
        })
        .collect::<anyhow::Result<_>>()?;
    let sum = |f: fn(&RunScene) -> usize| scenes.iter().map(f).sum::<usize>();
    let (on_table, cleared, picks, placed) =
        (sum(|s| s.on_table), sum(|s| s.cleared), sum(|s| s.picks), sum(|s| s.placed));
    let (first_attempts, first_placed) = (sum(|s| s.first_attempts), sum(|s| s.first_placed));
    let mut all_failures: BTreeMap<String, usize> = BTreeMap::new();
    let mut stops: BTreeMap<String, usize> = BTreeMap::new();
    for s in &scenes {
        for (kind, n) in &s.failures {
            *all_failures.entry(kind.clone()).or_insert(0) += n;
        }
        *stops.entry(s.stopped_by.clone()).or_insert(0) += 1;
    }
    let wrong: Vec<Value> = scenes.iter().flat_map(|s| s.wrong_picks.clone()).collect();
    let failed: Vec<Value> = scenes.iter().flat_map(|s| s.failed_picks.clone()).collect();
    let cycle_s: Vec<f64> = scenes.iter().flat_map(|s| s.cycle_s.clone()).collect();
    let vision_ms: Vec<f64> = scenes.iter().flat_map(|s| s.vision_ms.clone()).collect();
    let n = scenes.len();
    let mut report = json!({
        "world": first.shared["world_name"],
        "seeds": first.range,
        "scenes": n,
        "calibration": first.shared["calibration"],
        "calibration_error": first.shared["calibration_error"],
        "cleared_fraction": cleared as f64 / on_table.max(1) as f64,
        "pick_success_rate": placed as f64 / picks.max(1) as f64,
        "first_attempt_success_rate": first_placed as f64 / first_attempts.max(1) as f64,
        "attempts_per_object": picks as f64 / placed.max(1) as f64,
        "wrong_model_picks": wrong.len(),
        "wrong_picks": wrong,
        "cycles_mean": sum(|s| s.cycles) as f64 / n.max(1) as f64,
        "cycle_s_mean": cycle_s.iter().sum::<f64>() / cycle_s.len().max(1) as f64,
        "vision_cycle_ms_median": marvin::eval::quantile(&vision_ms, 0.5),
        "failures": all_failures,
        "failed_picks": failed,
        "stopped_by": stops,
        "pushing_picks": sum(|s| s.pushing_picks),
        "pushing_placed": sum(|s| s.pushing_placed),
        "unsettled_scenes": scenes.iter().filter(|s| s.unsettled).count(),
        "version": first.version,
    });
    marvin::eval::add_intervals(
        &mut report,
        &[
            ("cleared_fraction", cleared, on_table),
            ("pick_success_rate", placed, picks),
            ("first_attempt_success_rate", first_placed, first_attempts),
        ],
    );
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::failed_picks;
    use marvin::engine::run::Cycle;
    use marvin::protocol::{PickOutcomeKind, PickReply};
    use nalgebra::Isometry3;
    use vision::matcher::model::Located;

    fn cycle(model: &str, outcome: Option<PickOutcomeKind>, detail: Option<&str>) -> Cycle {
        let located = Located {
            model: model.into(),
            cam_from_model: Isometry3::identity(),
            support: 0.1,
            support_fraction: 0.5,
            scene_lines: Vec::new(),
            image_support: 0.9,
            grasps: Vec::new(),
        };
        let reply = PickReply {
            outcome,
            detail: detail.map(str::to_string),
            plan_ms: 1.0,
            motion_s: 1.0,
            grasp_index: 0,
            closed_opening_mm: None,
            grip_past_com_mm: None,
            tcp_path_base_m: Vec::new(),
        };
        Cycle { located: vec![located], chosen: Some(0), outcome: Some(Ok(reply)), ..Cycle::timed(Vec::new()) }
    }

    #[test]
    fn each_failed_pick_is_named_with_where_the_part_came_to_rest() {
        let cycles = [
            cycle("block", Some(PickOutcomeKind::Placed), None),
            cycle("wedge", Some(PickOutcomeKind::Drop), Some("it came to rest at (0.4, 0.3, 0.0)")),
            Cycle::timed(Vec::new()),
        ];
        let failed = failed_picks(165, &cycles);
        assert_eq!(failed.len(), 1, "{failed:?}");
        assert_eq!(failed[0]["seed"], 165);
        assert_eq!(failed[0]["cycle"], 2);
        assert_eq!(failed[0]["model"], "wedge");
        assert_eq!(failed[0]["outcome"], "drop");
        assert_eq!(failed[0]["detail"], "it came to rest at (0.4, 0.3, 0.0)");
    }
}
