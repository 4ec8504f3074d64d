//! `marvin run`: the main job. A robot server (in-process on loopback, or `--connect`ed), the
//! hand-eye transform (from `--hand-eye`, or calibrated first), then pick cycles until the table
//! is clear; one line per cycle, a summary, and the stage times beside the paper's Table 1.
//! `marvin eval run`: seeded runs against the truth.

use super::calibrate::Cell;
use super::output::emit;
use anyhow::Context;
use marvin::calibrate::{CalibrateConfig, Calibration, calibrate};
use marvin::client::Client;
use marvin::protocol::{PickOutcomeKind, TruthReply, WirePose};
use marvin::recording::{Recording, Sink};
use marvin::run::{Cycle, RunConfig, RunEvent, RunReport, Stop, table1};
use nalgebra::Isometry3;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The command's arguments.
pub struct RunArgs {
    pub world: PathBuf,
    pub seed: Option<u64>,
    pub connect: Option<String>,
    pub hand_eye: Option<PathBuf>,
    pub max_cycles: usize,
    pub json: bool,
    /// Where to record the run for rerun, if anywhere.
    pub rerun: Option<Sink>,
}

/// What evaluation learns from the simulation after the fact (a local server only).
#[derive(Debug, Clone, Default)]
pub struct RunTruth {
    /// Objects on the table (not in a bin) at the start, and in a bin at the end.
    pub on_table_at_start: usize,
    pub in_bin_at_end: usize,
    /// For each pick tried: the object of the chosen model that lay within 20 mm of where
    /// vision put it (its `id`), or `None` (a pick at nothing of that model).
    pub targets: Vec<Option<u32>>,
    /// Why the scene had not settled when the cell started, if it had not.
    pub unsettled: Option<String>,
}

impl RunTruth {
    /// Picks at a pose where no object of the model chosen lay.
    pub fn wrong_picks(&self) -> usize {
        self.targets.iter().filter(|t| t.is_none()).count()
    }

    /// For each pick tried, whether it was the first at its object (`false` for a wrong pick).
    pub fn first_attempts(&self) -> Vec<bool> {
        let mut seen = std::collections::BTreeSet::new();
        self.targets.iter().map(|t| t.is_some_and(|id| seen.insert(id))).collect()
    }
}

/// A run with everything evaluation needs: the report, the calibration's error (if calibrated
/// here against a local server), the truth.
pub struct Outcome {
    pub report: RunReport,
    pub truth: Option<RunTruth>,
    pub calibration_error: CalibrationError,
}

/// The nearest true object of `model` to vision's pose of it: its id and how far, metres.
fn nearest_true(truth: &TruthReply, model: &str, cam_from_model: &Isometry3<f64>) -> Option<(u32, f64)> {
    let world_from_cam = truth.world_from_cam.to_isometry("world_from_cam").ok()?;
    let p = world_from_cam * cam_from_model;
    truth
        .objects
        .iter()
        .filter(|o| o.model == model)
        .filter_map(|o| Some((o.id, o.world_from_model.to_isometry("world_from_model").ok()?)))
        .map(|(id, w)| (id, (w.translation.vector - p.translation.vector).norm()))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// A pick is at an object of the model chosen when one lies this near vision's pose, metres.
const TARGET_THERE_M: f64 = 0.02;

/// Where a run's hand-eye transform comes from.
pub enum HandEye {
    /// Calibrated at the start of the run.
    Calibrate,
    /// A calibration file.
    File(PathBuf),
    /// Known already (an evaluation calibrates once for all its scenes).
    Known(Isometry3<f64>),
}

/// The calibration's error against the truth: mm and degrees.
type CalibrationError = Option<(f64, f64)>;

/// The hand-eye transform: from a file, or calibrated now (with its error against the truth
/// when the server is local).
fn hand_eye(
    client: &mut Client,
    library: &mesh::Library,
    source: &HandEye,
    seed: u64,
    local: bool,
    quiet: bool,
) -> anyhow::Result<(Isometry3<f64>, CalibrationError, Option<Calibration>)> {
    if let HandEye::Known(x) = source {
        return Ok((*x, None, None));
    }
    if let HandEye::File(f) = source {
        let he = hand_eye::HandEyeFile::load(f)?;
        return Ok((he.cam_from_base.to_isometry(), None, None));
    }
    let config = CalibrateConfig { seed, ..CalibrateConfig::default() };
    let mut progress = |line: &str| {
        if !quiet {
            eprintln!("  calibration {line}");
        }
    };
    let c = calibrate(client, library, &config, &mut |_, _| Ok(()), &mut progress).context("calibrating")?;
    let x = c.solution.cam_from_base;
    let error = if local {
        let t = client.truth()?.cam_from_base.to_isometry("cam_from_base")?;
        Some((
            (x.translation.vector - t.translation.vector).norm() * 1e3,
            x.rotation.angle_to(&t.rotation).to_degrees(),
        ))
    } else {
        None
    };
    Ok((x, error, Some(c)))
}

/// One run on `cell`, with the hand-eye transform from `source`; `cycle_line` hears of each
/// cycle; `recording`, if any, is given everything to record.
#[allow(clippy::too_many_arguments)]
pub fn run_once(
    cell: &Cell,
    scn: &sim::Scenario,
    seed: u64,
    source: &HandEye,
    config: &RunConfig,
    quiet: bool,
    cycle_line: &mut dyn FnMut(&Cycle) -> String,
    mut recording: Option<&mut Recording>,
) -> anyhow::Result<Outcome> {
    let library = &scn.library;
    let mut client = cell.connect()?;
    let local = cell.is_local();
    let (cam_from_base, calibration_error, calibration) = hand_eye(&mut client, library, source, seed, local, quiet)?;
    // The arm as the recording draws it, from the world file's URDF.
    let arm = match recording.is_some() {
        true => Some(marvin::pick::Workcell::new(scn)?.arm),
        false => None,
    };
    if let Some(r) = recording.as_deref_mut() {
        if let Some(c) = &calibration {
            let truth = if local { Some(client.truth()?.cam_from_base.to_isometry("cam_from_base")?) } else { None };
            r.calibration(c, truth.as_ref())?;
        } else {
            r.calibration_known(&cam_from_base)?;
        }
        r.bins(&client.hello(std::env::var("MARVIN_TOKEN").ok().as_deref())?.bin_boxes)?;
        r.cell_layout(scn)?;
    }
    client.set_hand_eye(WirePose::new(None, &cam_from_base))?;
    let mut truth = local.then(RunTruth::default);
    if let Some(t) = truth.as_mut() {
        let start = client.truth()?;
        t.on_table_at_start = start.objects.iter().filter(|o| !o.in_bin).count();
        t.unsettled = start.unsettled;
    }
    let mut before_pick = |c: &mut Client, _k: usize, l: &vision::matcher::Located| -> anyhow::Result<()> {
        if let Some(t) = truth.as_mut() {
            let now = c.truth()?;
            let nearest = nearest_true(&now, &l.model, &l.cam_from_model);
            t.targets.push(nearest.filter(|(_, d)| *d < TARGET_THERE_M).map(|(id, _)| id));
        }
        Ok(())
    };
    let mut sim_time = 0.0;
    let mut observe = |event: RunEvent<'_>| -> anyhow::Result<()> {
        match event {
            RunEvent::Captured { cycle, capture, pair, front_end } => {
                sim_time = capture.sim_time_s;
                if let Some(r) = recording.as_deref_mut() {
                    r.at(cycle, sim_time);
                    r.capture(capture, pair, front_end)?;
                }
            }
            RunEvent::Located { located, .. } => {
                if let Some(r) = recording.as_deref_mut() {
                    r.located(located, library)?;
                }
            }
            RunEvent::Done(c) => {
                let line = cycle_line(c);
                if let (Some(r), Some(arm)) = (recording.as_deref_mut(), arm.as_ref()) {
                    r.cycle(c, &line)?;
                    let q: robot::Joints =
                        std::array::from_fn(|k| c.joints.get(&arm.joint(k).name).copied().unwrap_or(0.0));
                    r.arm(arm, &q, c.gripper_opening_m)?;
                }
            }
        }
        Ok(())
    };
    let report = marvin::run::run(&mut client, library, config, &cam_from_base, &mut before_pick, &mut observe)?;
    if let (Some(r), true) = (recording, local) {
        r.at(report.cycles.len(), sim_time);
        r.truth(&client.truth()?, library)?;
    }
    if let Some(t) = truth.as_mut() {
        t.in_bin_at_end = client.truth()?.objects.iter().filter(|o| o.in_bin).count();
    }
    client.bye()?;
    Ok(Outcome { report, truth, calibration_error })
}

fn outcome_name(c: &Cycle) -> String {
    match &c.outcome {
        None => "nothing picked".into(),
        Some(Ok(r)) => match r.outcome {
            Some(PickOutcomeKind::Placed) => "placed".into(),
            Some(k) => serde_json::to_value(k).ok().and_then(|v| v.as_str().map(str::to_string)).unwrap_or_default(),
            None => "planned only".into(),
        },
        Some(Err(e)) => format!("refused: {e}"),
    }
}

fn cycle_json(c: &Cycle) -> Value {
    json!({
        "located": c.located.iter().map(|l| json!({ "model": l.model, "support": l.support_fraction, "image_support": l.image_support })).collect::<Vec<_>>(),
        "chosen": c.chosen.map(|i| c.located[i].model.clone()),
        "outcome": outcome_name(c),
        "detail": c.outcome.as_ref().and_then(|o| o.as_ref().ok()).and_then(|r| r.detail.clone()),
        "unplannable": c.unplannable,
        "vision_ms": c.vision_ms(),
        "cycle_s": c.cycle_s,
    })
}

/// Failures by kind, over every pick tried.
pub fn failures(cycles: &[Cycle]) -> BTreeMap<String, usize> {
    let mut out = BTreeMap::new();
    for c in cycles.iter().filter(|c| c.chosen.is_some()) {
        let name = outcome_name(c);
        if name != "placed" {
            *out.entry(name.split(':').next().unwrap_or("").to_string()).or_insert(0) += 1;
        }
    }
    out
}

pub fn run(args: RunArgs) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&args.world)?;
    let seed = args.seed.unwrap_or(scn.world.seed);
    if !args.json {
        eprintln!("settling {} (seed {seed}) ...", args.world.display());
    }
    let cell = Cell::start(&args.world, seed, args.connect.as_deref())?;
    let quiet = args.json;
    let mut k = 0;
    let mut line = |c: &Cycle| {
        k += 1;
        let chosen = c.chosen.map_or("-".to_string(), |i| c.located[i].model.clone());
        let line = format!(
            "cycle {k}: {} located, {chosen} chosen: {} ({:.0} ms vision, {:.1} s)",
            c.located.len(),
            outcome_name(c),
            c.vision_ms(),
            c.cycle_s
        );
        if !quiet {
            eprintln!("{line}");
        }
        line
    };
    let config = RunConfig { max_cycles: args.max_cycles, ..RunConfig::default() };
    let source = args.hand_eye.clone().map_or(HandEye::Calibrate, HandEye::File);
    let mut recording = args.rerun.as_ref().map(Recording::start).transpose()?;
    let out = run_once(&cell, &scn, seed, &source, &config, quiet, &mut line, recording.as_mut())?;
    cell.stop()?;
    if let Some(r) = recording {
        r.finish()?;
        if !quiet {
            match &args.rerun {
                Some(Sink::File(path)) => {
                    eprintln!("recorded the run in {} (open it with `rerun {}`)", path.display(), path.display())
                }
                _ => eprintln!("streamed the run to the rerun viewer"),
            }
        }
    }
    let cycles = &out.report.cycles;
    let placed = cycles.iter().filter(|c| outcome_name(c) == "placed").count();
    let picks = cycles.iter().filter(|c| c.chosen.is_some()).count();
    let (rows, efficiency) = table1(cycles);
    let stop = match out.report.stop {
        Stop::NothingLocated => "nothing more located",
        Stop::NothingPickable => "nothing located could be picked",
        Stop::MaxCycles => "the cycle limit",
    };
    if args.json {
        let mut doc = json!({
            "cycles": cycles.iter().map(cycle_json).collect::<Vec<_>>(),
            "stopped_by": stop,
            "picks": picks,
            "placed": placed,
            "failures": failures(cycles),
            "table1": rows,
            "parallel_efficiency": efficiency,
        });
        if let Some(t) = &out.truth {
            doc["truth"] = json!({
                "on_table_at_start": t.on_table_at_start,
                "in_bin_at_end": t.in_bin_at_end,
                "wrong_model_picks": t.wrong_picks(),
            });
        }
        if let Some((mm, deg)) = out.calibration_error {
            doc["calibration_error"] = json!({ "translation_mm": mm, "rotation_deg": deg });
        }
        return emit(&doc.to_string());
    }
    emit(&format!("stopped by {stop}: {placed} of {picks} picks placed; failures {:?}", failures(cycles)))?;
    if let Some(t) = &out.truth {
        emit(&format!(
            "against the simulation's truth: {} of {} objects cleared into the bin; {} picks at nothing of the model chosen",
            t.in_bin_at_end,
            t.on_table_at_start,
            t.wrong_picks()
        ))?;
    }
    if let Some((mm, deg)) = out.calibration_error {
        emit(&format!("calibration: {mm:.2} mm, {deg:.3} deg from the true camera pose"))?;
    }
    super::output::table1(
        "Table 1 (median per cycle, ms; the front end's stages in processor time over 8 slices):",
        &rows,
        efficiency,
    )
}

/// `marvin eval run`: seeded end-to-end runs, one calibration (on the first seed's scene)
/// shared by all: the cameras and the robot stand where the world file puts them in every scene.
pub fn eval(world: &Path, scenes: u64, seed: u64, json: bool) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(world)?;
    let cell = Cell::start(world, seed, None)?;
    let mut client = cell.connect()?;
    let (cam_from_base, calibration_error, _) =
        hand_eye(&mut client, &scn.library, &HandEye::Calibrate, seed, true, true)?;
    client.bye()?;
    cell.stop()?;
    let progress = super::output::Progress::new(scenes, json);
    let (mut on_table, mut cleared, mut picks, mut placed, mut wrong) = (0, 0, 0, 0, 0);
    let (mut first_attempts, mut first_placed, mut unsettled) = (0, 0, 0);
    let (mut cycles, mut cycle_s, mut vision_ms) = (0usize, Vec::new(), Vec::new());
    let mut all_failures: BTreeMap<String, usize> = BTreeMap::new();
    let mut stops: BTreeMap<&'static str, usize> = BTreeMap::new();
    for k in 0..scenes {
        let s = seed + k;
        let clock = Instant::now();
        let cell = Cell::start(world, s, None)?;
        let known = HandEye::Known(cam_from_base);
        let out = run_once(&cell, &scn, s, &known, &RunConfig::default(), true, &mut |_| String::new(), None)?;
        cell.stop()?;
        let truth = out.truth.context("a local server gives the truth")?;
        let r = &out.report;
        let (p, ok) = (
            r.cycles.iter().filter(|c| c.chosen.is_some()).count(),
            r.cycles.iter().filter(|c| outcome_name(c) == "placed").count(),
        );
        (on_table, cleared, picks, placed) =
            (on_table + truth.on_table_at_start, cleared + truth.in_bin_at_end, picks + p, placed + ok);
        wrong += truth.wrong_picks();
        unsettled += usize::from(truth.unsettled.is_some());
        let tried = r.cycles.iter().filter(|c| c.chosen.is_some());
        for (c, first) in tried.zip(truth.first_attempts()) {
            first_attempts += usize::from(first);
            first_placed += usize::from(first && outcome_name(c) == "placed");
        }
        cycles += r.cycles.len();
        cycle_s.extend(r.cycles.iter().map(|c| c.cycle_s));
        vision_ms.extend(r.cycles.iter().map(Cycle::vision_ms));
        for (kind, n) in failures(&r.cycles) {
            *all_failures.entry(kind).or_insert(0) += n;
        }
        let stop = match r.stop {
            Stop::NothingLocated => "nothing_located",
            Stop::NothingPickable => "nothing_pickable",
            Stop::MaxCycles => "max_cycles",
        };
        *stops.entry(stop).or_insert(0) += 1;
        progress.step(format!(
            "seed {s}: {} of {} cleared, {ok} of {p} picks placed, stopped by {stop} ({:.1} s)",
            truth.in_bin_at_end,
            truth.on_table_at_start,
            clock.elapsed().as_secs_f64()
        ));
    }
    progress.finish();
    let q = |v: &[f64], p: f64| marvin::eval::quantile(v, p);
    let report = json!({
        "world": scn.world.name,
        "seeds": [seed, seed + scenes - 1],
        "scenes": scenes,
        "calibration": "one, on the first seed's scene, shared by all scenes",
        "calibration_error": calibration_error.map(|(mm, deg)| json!({ "translation_mm": mm, "rotation_deg": deg })),
        "cleared_fraction": cleared as f64 / on_table.max(1) as f64,
        "pick_success_rate": placed as f64 / picks.max(1) as f64,
        "first_attempt_success_rate": first_placed as f64 / first_attempts.max(1) as f64,
        "attempts_per_object": picks as f64 / placed.max(1) as f64,
        "wrong_model_picks": wrong,
        "cycles_mean": cycles as f64 / scenes.max(1) as f64,
        "cycle_s_mean": cycle_s.iter().sum::<f64>() / cycle_s.len().max(1) as f64,
        "vision_cycle_ms_median": q(&vision_ms, 0.5),
        "failures": all_failures,
        "stopped_by": stops,
        "unsettled_scenes": unsettled,
    });
    if json { emit(&report.to_string()) } else { emit(&serde_json::to_string_pretty(&report)?) }
}

#[cfg(test)]
mod tests {
    use super::RunTruth;

    #[test]
    fn a_pick_is_a_first_attempt_only_at_an_object_not_tried_before() {
        let t = RunTruth { targets: vec![Some(3), None, Some(3), Some(5), None], ..RunTruth::default() };
        assert_eq!(t.first_attempts(), [true, false, false, true, false]);
        assert_eq!(t.wrong_picks(), 2);
    }
}
