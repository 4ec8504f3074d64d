//! `marvin run`: the main job. A robot server (in-process on loopback, or `--connect`ed), the
//! cameras (from `--cameras`, as the server publishes them, or calibrated first from the board),
//! the hand-eye transform (from `--hand-eye`, or calibrated next), then pick cycles until the table
//! is clear ([`super::session`]); one line per cycle, a summary, and the stage times beside the
//! paper's Table 1.

use super::calibrate::Cell;
use super::calibrate::load_cameras;
use super::eval_run::Judge;
use super::output::emit;
use super::session::{HandEye, failures, outcome_name, run_once};
use marvin::engine::recording::{Recording, Sink};
use marvin::engine::run::{Cycle, RunConfig, Stop, table1};
use serde_json::{Value, json};
use std::path::PathBuf;

/// The command's arguments.
pub struct RunArgs {
    pub world: PathBuf,
    pub seed: Option<u64>,
    pub connect: Option<String>,
    pub hand_eye: Option<PathBuf>,
    /// A camera calibration file (`marvin calibrate cameras`).
    pub cameras: Option<PathBuf>,
    pub max_cycles: usize,
    pub json: bool,
    /// Where to record the run for rerun, if anywhere.
    pub rerun: Option<Sink>,
    /// A folder for each cycle's pair of images, if any.
    pub save_captures: Option<PathBuf>,
}

fn cycle_json(c: &Cycle) -> Value {
    let reply = c.reply();
    json!({
        "located": c.located.iter().enumerate().map(|(i, l)| json!({
            "model": l.model, "support": l.support_fraction, "image_support": l.image_support,
            "in_doubt": c.in_doubt.get(i).copied().unwrap_or(false),
        })).collect::<Vec<_>>(),
        "chosen": c.chosen_model(),
        "outcome": outcome_name(c),
        "detail": reply.and_then(|r| r.detail.clone()),
        // Which grasp the plan used, how far the jaws closed on the part and how deep the
        // fingertips reached past its centre of mass: what to look at first when a part slips
        // or drops.
        "grasp_index": reply.map(|r| r.grasp_index),
        "closed_opening_mm": reply.and_then(|r| r.closed_opening_mm),
        "grip_past_com_mm": reply.and_then(|r| r.grip_past_com_mm),
        "unplannable": c.unplannable,
        "pushing_neighbours": c.pushing_neighbours,
        "vision_ms": c.vision_ms(),
        "cycle_s": c.cycle_s,
    })
}

/// A run that failed in a realistic cell, said so: there the cameras are calibrated from the
/// board, but vision does not yet find the hand-eye flag through them reliably.
fn realistic_hint(e: anyhow::Error, scn: &sim::Scenario, args: &RunArgs) -> anyhow::Error {
    let effects = scn.world.effects();
    let calibrating = e.chain().any(|c| c.to_string() == "calibrating");
    if !calibrating || args.connect.is_some() || !(effects.mounting || effects.sensor || effects.specular) {
        return e;
    }
    e.context(format!(
        "{} is a realistic cell (`realism`): its cameras were calibrated from the board, but vision \
         does not yet find the hand-eye flag in its images often enough (README, \"The realistic \
         cell\"); its ideal copy in worlds/ideal/ runs",
        args.world.display()
    ))
}

pub fn run(args: RunArgs) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&args.world)?;
    let seed = args.seed.unwrap_or(scn.world.seed);
    if !args.json {
        eprintln!("settling {} (seed {seed}) ...", args.world.display());
    }
    let cell = Cell::start(&args.world, seed, args.connect.as_deref())?;
    let quiet = args.json;
    if let (Some(server), false) = (cell.local(), quiet) {
        // Another process may watch (`status`) while it runs; the socket serves no truth.
        eprintln!("the run's robot server listens on {}", server.addr());
    }
    let mut k = 0;
    let mut line = |c: &Cycle| {
        k += 1;
        let chosen = c.chosen_model().unwrap_or("-");
        let doubted = c.in_doubt.iter().filter(|d| **d).count();
        let doubted = if doubted > 0 { format!(" ({doubted} in doubt)") } else { String::new() };
        let line = format!(
            "cycle {k}: {} located{doubted}, {chosen} chosen: {} ({:.0} ms vision, {:.1} s)",
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
    let cameras = args.cameras.as_deref().map(load_cameras).transpose()?;
    let config = RunConfig { max_cycles: args.max_cycles, cameras, ..RunConfig::default() };
    let source = args.hand_eye.clone().map_or(HandEye::Calibrate, HandEye::File);
    let mut recording = args.rerun.as_ref().map(Recording::start).transpose()?;
    let mut judge = Judge::new(cell.local(), &scn.library);
    let captures = args.save_captures.as_deref();
    let report =
        run_once(&cell, &scn, seed, &source, &config, quiet, &mut line, recording.as_mut(), captures, &mut judge)
            .map_err(|e| realistic_hint(e, &scn, &args))?;
    let verdict = judge.verdict();
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
        verdict.add_to(&mut doc);
        return emit(&doc.to_string());
    }
    emit(&format!("stopped by {stop}: {placed} of {picks} picks placed; failures {:?}", failures(cycles)))?;
    for line in verdict.summary() {
        emit(&line)?;
    }
    super::output::table1(
        "Table 1 (median per cycle, ms; the front end's stages in processor time over 8 slices):",
        &rows,
        efficiency,
    )
}
