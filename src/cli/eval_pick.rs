//! `marvin eval pick`: seeded physical picks, in clutter and one object at a time, every attempt
//! counted; batched like `eval run` (`--shard`, `--out`, `--resume`, `--jobs`, and `marvin eval
//! merge` of the records): trial k is a clutter scene of seed + k cleared object by object and
//! each model alone dropped with seed + k.

use super::batch::{Batch, Runner, print_report};
use super::output::{emit, settle};
use anyhow::Context;
use marvin::eval::batch::Record;
use marvin::server::pick::{ObjectPicks, PickOutcome, clear_scene, load, pickable_models, single_object_scenario};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::collections::BTreeMap;
use std::time::Instant;

/// What `eval pick` keeps of one trial.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PickTrial {
    /// The clutter scene's objects, each with every pick tried at it.
    pub clutter: Vec<ObjectPicks>,
    pub clutter_settled: bool,
    /// Each model alone: its pick, and whether its scene settled.
    pub single: Vec<(PickOutcome, bool)>,
    /// Wall time of the trial: it differs from machine to machine and run to run.
    pub wall_s: f64,
}

/// `marvin eval pick`.
pub fn run(b: &Batch) -> anyhow::Result<()> {
    let (scn, work) = load(&b.world)?;
    let runner = Runner::open(b, "pick")?;
    let models = pickable_models(&scn);
    let trial = |s: u64| {
        let started = Instant::now();
        let clutter_trial = || -> anyhow::Result<(Vec<ObjectPicks>, bool)> {
            let (scene, settled) = settle(&scn, s);
            Ok((clear_scene(&scn, &work, &scene)?, settled))
        };
        let singles = || -> anyhow::Result<Vec<(PickOutcome, bool)>> {
            models
                .par_iter()
                .map(|model| {
                    let one = single_object_scenario(&scn, model);
                    let (scene, settled) = settle(&one, s);
                    Ok((marvin::server::pick::PickCell::new(&one, &work, &scene)?.pick(1, s)?, settled))
                })
                .collect()
        };
        let (clutter, single) = rayon::join(clutter_trial, singles);
        let ((clutter, clutter_settled), single) = (clutter?, single?);
        let cleared = clutter.iter().filter(|o| o.cleared()).count();
        let attempts: usize = clutter.iter().map(|o| o.attempts.len()).sum();
        let placed = single.iter().filter(|(o, _)| o.placed).count();
        let line = format!(
            "{cleared} of {} cleared in {attempts} picks; {placed} of {} single picks placed",
            clutter.len(),
            single.len()
        );
        let wall_s = started.elapsed().as_secs_f64();
        Ok((serde_json::to_value(PickTrial { clutter, clutter_settled, single, wall_s })?, line))
    };
    let shared = json!({ "world_name": scn.world.name, "models": models });
    let records = runner.run(&shared, &trial)?;
    let report = summarise(&records)?;
    if b.json {
        return print_report(report, b.shard, true);
    }
    print_summary(&report)
}

/// The summary of `eval pick` records (sorted by seed), as one process over them prints it.
/// Everything but `wall_s` is a function of the records' trials alone.
pub fn summarise(records: &[Record]) -> anyhow::Result<serde_json::Value> {
    let first = records.first().context("no trials to summarise")?;
    let trials: Vec<PickTrial> = records
        .iter()
        .map(|r| {
            serde_json::from_value(r.scene.clone())
                .with_context(|| format!("seed {}: not an `eval pick` trial", r.seed))
        })
        .collect::<anyhow::Result<_>>()?;
    let models: Vec<String> = serde_json::from_value(first.shared["models"].clone()).context("the records' models")?;
    let objects: Vec<&ObjectPicks> = trials.iter().flat_map(|t| &t.clutter).collect();
    let single: Vec<Trial<PickOutcome>> = trials
        .iter()
        .flat_map(|t| t.single.iter().map(|(o, settled)| Trial { outcome: o.clone(), settled: *settled }))
        .collect();
    let wall_s = trials.iter().map(|t| t.wall_s).sum();
    let unsettled = trials.iter().filter(|t| !t.clutter_settled).count();
    let mut report = report(&objects, &single, &models, wall_s, unsettled);
    report["world"] = first.shared["world_name"].clone();
    report["seeds"] = json!(first.range);
    report["trials"] = json!(records.len());
    report["version"] = json!(first.version);
    Ok(report)
}

/// A scene's outcome and whether it settled.
struct Trial<T> {
    outcome: T,
    settled: bool,
}

/// Placed of these picks, as a fraction.
fn placed_fraction<'a>(picks: impl IntoIterator<Item = &'a PickOutcome>) -> f64 {
    let (placed, all) = placed_of(picks);
    placed as f64 / all.max(1) as f64
}

/// How many of `picks` placed their object, and of how many.
fn placed_of<'a>(picks: impl IntoIterator<Item = &'a PickOutcome>) -> (usize, usize) {
    picks.into_iter().fold((0, 0), |(placed, all), p| (placed + p.placed as usize, all + 1))
}

/// Failed picks by kind.
fn failures<'a>(picks: impl IntoIterator<Item = &'a PickOutcome>) -> BTreeMap<String, usize> {
    let mut out = BTreeMap::new();
    for p in picks.into_iter().filter(|p| !p.placed) {
        *out.entry(p.result.clone()).or_default() += 1;
    }
    out
}

fn report(
    objects: &[&ObjectPicks],
    single: &[Trial<PickOutcome>],
    models: &[String],
    wall_s: f64,
    unsettled_clutter: usize,
) -> serde_json::Value {
    let attempts: Vec<&PickOutcome> = objects.iter().flat_map(|o| &o.attempts).collect();
    let firsts = objects.iter().filter_map(|o| o.attempts.first());
    let lasts = objects.iter().filter_map(|o| o.last());
    let single_picks: Vec<&PickOutcome> = single.iter().map(|t| &t.outcome).collect();
    let by_model: BTreeMap<&String, f64> =
        models.iter().map(|m| (m, placed_fraction(single_picks.iter().copied().filter(|o| &o.model == m)))).collect();
    let simulated_s: f64 = attempts.iter().chain(&single_picks).map(|o| o.simulated_s).sum();
    let cleared = objects.iter().filter(|o| o.cleared()).count();
    let counts = [
        ("cleared_fraction", (cleared, objects.len())),
        ("first_attempt_success_rate", placed_of(objects.iter().filter_map(|o| o.attempts.first()))),
        ("pick_success_rate", placed_of(attempts.iter().copied())),
        ("single_success_rate", placed_of(single_picks.iter().copied())),
    ];
    let mut report = json!({
        "cleared_fraction": objects.iter().filter(|o| o.cleared()).count() as f64 / objects.len().max(1) as f64,
        "first_attempt_success_rate": placed_fraction(firsts),
        "pick_success_rate": placed_fraction(attempts.iter().copied()),
        "attempts_per_object": attempts.len() as f64 / objects.len().max(1) as f64,
        "failures": failures(attempts.iter().copied()),
        "failures_left_on_table": failures(lasts),
        "single_success_rate": placed_fraction(single_picks.iter().copied()),
        "single_by_model": by_model,
        "single_failures": failures(single_picks.iter().copied()),
        "objects": objects.len(),
        "picks": {"clutter": attempts.len(), "single": single_picks.len()},
        "unsettled_scenes": {
            "clutter": unsettled_clutter,
            "single": single.iter().filter(|t| !t.settled).count(),
        },
        "simulated_s": simulated_s,
        "wall_s": wall_s,
    });
    let fractions: Vec<(&str, usize, usize)> = counts.iter().map(|&(key, (k, n))| (key, k, n)).collect();
    marvin::eval::add_intervals(&mut report, &fractions);
    report
}

fn print_summary(r: &serde_json::Value) -> anyhow::Result<()> {
    let f = |k: &str| r[k].as_f64().unwrap_or(f64::NAN);
    let ci = |k: &str| {
        let v = &r[format!("{k}_ci95")];
        format!("[{:.3}, {:.3}]", v[0].as_f64().unwrap_or(f64::NAN), v[1].as_f64().unwrap_or(f64::NAN))
    };
    emit(&format!(
        "clutter: {:.3} {} of {} objects cleared; {:.3} {} placed at the first attempt; {:.3} {} of {} picks placed ({:.2} an object)",
        f("cleared_fraction"),
        ci("cleared_fraction"),
        r["objects"],
        f("first_attempt_success_rate"),
        ci("first_attempt_success_rate"),
        f("pick_success_rate"),
        ci("pick_success_rate"),
        r["picks"]["clutter"],
        f("attempts_per_object"),
    ))?;
    emit(&format!(
        "  failures, every attempt: {}; of objects left on the table: {}",
        r["failures"], r["failures_left_on_table"]
    ))?;
    emit(&format!(
        "single objects: {:.3} {} of {} placed",
        f("single_success_rate"),
        ci("single_success_rate"),
        r["picks"]["single"]
    ))?;
    if let Some(by) = r["single_by_model"].as_object() {
        for (m, v) in by {
            emit(&format!("  {m:<10} {:.3}", v.as_f64().unwrap_or(f64::NAN)))?;
        }
    }
    emit(&format!("  failures: {}", r["single_failures"]))?;
    emit(&format!("unsettled scenes: {}", r["unsettled_scenes"]))?;
    emit(&format!("{:.0} s simulated in {:.0} s", f("simulated_s"), f("wall_s")))
}
