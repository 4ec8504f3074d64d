//! `marvin run`: the main job. A robot server (in-process on loopback, or `--connect`ed), the
//! hand-eye transform (from `--hand-eye`, or calibrated first), then pick cycles until the table
//! is clear; one line per cycle, a summary, and the stage times beside the paper's Table 1.
//! (`marvin eval run`, in [`super::eval_run`], watches it through [`Watcher`].)

use super::calibrate::Cell;
use super::eval_run::Judge;
use super::output::emit;
use anyhow::Context;
use marvin::calibrate::{CalibrateConfig, Calibration, calibrate};
use marvin::client::Client;
use marvin::protocol::{PickOutcomeKind, WirePose};
use marvin::recording::{Recording, Sink};
use marvin::run::{Cycle, RunConfig, RunEvent, RunReport, Stop, table1};
use nalgebra::Isometry3;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::PathBuf;
use vision::matcher::Located;

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

/// Where a run's hand-eye transform comes from.
pub enum HandEye {
    /// Calibrated at the start of the run.
    Calibrate,
    /// A calibration file.
    File(PathBuf),
    /// Known already (an evaluation calibrates once for all its scenes).
    Known(Isometry3<f64>),
}

/// Who watches a run from outside it: evaluation, reading the simulation through the server's
/// evaluation-only request, and judging after the fact. Nothing the run decides comes from it.
pub trait Watcher {
    /// The hand-eye transform is known (`calibration` is the run's own, if it calibrated).
    fn started(
        &mut self,
        client: &mut Client,
        cam_from_base: &Isometry3<f64>,
        calibration: Option<&Calibration>,
        recording: Option<&mut Recording>,
    ) -> anyhow::Result<()>;
    /// Just before cycle `cycle` picks `chosen`.
    fn before_pick(&mut self, client: &mut Client, cycle: usize, chosen: &Located) -> anyhow::Result<()>;
    /// The run is over.
    fn finished(&mut self, client: &mut Client, recording: Option<&mut Recording>) -> anyhow::Result<()>;
}

/// The hand-eye transform: known, from a file, or calibrated now.
pub fn hand_eye(
    client: &mut Client,
    library: &mesh::Library,
    source: &HandEye,
    seed: u64,
    quiet: bool,
) -> anyhow::Result<(Isometry3<f64>, Option<Calibration>)> {
    if let HandEye::Known(x) = source {
        return Ok((*x, None));
    }
    if let HandEye::File(f) = source {
        let he = hand_eye::HandEyeFile::load(f)?;
        return Ok((he.cam_from_base.to_isometry(), None));
    }
    let config = CalibrateConfig { seed, ..CalibrateConfig::default() };
    let mut progress = |line: &str| {
        if !quiet {
            eprintln!("  calibration {line}");
        }
    };
    let c = calibrate(client, library, &config, &mut |_, _| Ok(()), &mut progress).context("calibrating")?;
    Ok((c.solution.cam_from_base, Some(c)))
}

/// One run on `cell`, with the hand-eye transform from `source`; `cycle_line` hears of each
/// cycle; `recording`, if any, is given everything to record; `watcher` watches.
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
    watcher: &mut dyn Watcher,
) -> anyhow::Result<RunReport> {
    let library = &scn.library;
    let mut client = cell.connect()?;
    let (cam_from_base, calibration) = hand_eye(&mut client, library, source, seed, quiet)?;
    // The arm as the recording draws it, from the world file's URDF.
    let arm = match recording.is_some() {
        true => Some(marvin::pick::Workcell::new(scn)?.arm),
        false => None,
    };
    if let Some(r) = recording.as_deref_mut() {
        match &calibration {
            Some(c) => r.calibration(c)?,
            None => r.calibration_known(&cam_from_base)?,
        }
        r.bins(&client.hello(std::env::var("MARVIN_TOKEN").ok().as_deref())?.bin_boxes)?;
        r.cell_layout(scn)?;
    }
    client.set_hand_eye(WirePose::new(None, &cam_from_base))?;
    watcher.started(&mut client, &cam_from_base, calibration.as_ref(), recording.as_deref_mut())?;
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
    let mut before_pick = |c: &mut Client, k: usize, l: &Located| watcher.before_pick(c, k, l);
    let report = marvin::run::run(&mut client, library, config, &cam_from_base, &mut before_pick, &mut observe)?;
    if let Some(r) = recording.as_deref_mut() {
        r.at(report.cycles.len(), sim_time);
    }
    watcher.finished(&mut client, recording)?;
    client.bye()?;
    Ok(report)
}

pub fn outcome_name(c: &Cycle) -> String {
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
    let mut judge = Judge::new(cell.is_local(), &scn.library);
    let report = run_once(&cell, &scn, seed, &source, &config, quiet, &mut line, recording.as_mut(), &mut judge)?;
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
    let cycles = &report.cycles;
    let placed = cycles.iter().filter(|c| outcome_name(c) == "placed").count();
    let picks = cycles.iter().filter(|c| c.chosen.is_some()).count();
    let (rows, efficiency) = table1(cycles);
    let stop = match report.stop {
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
        judge.add_to(&mut doc);
        return emit(&doc.to_string());
    }
    emit(&format!("stopped by {stop}: {placed} of {picks} picks placed; failures {:?}", failures(cycles)))?;
    for line in judge.summary() {
        emit(&line)?;
    }
    super::output::table1(
        "Table 1 (median per cycle, ms; the front end's stages in processor time over 8 slices):",
        &rows,
        efficiency,
    )
}
