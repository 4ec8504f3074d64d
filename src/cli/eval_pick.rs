//! `marvin eval pick`: seeded physical picks, in clutter and one object at a time, every attempt
//! counted.

use super::output::{emit, settle};
use marvin::server::pick::{ObjectPicks, PickOutcome, clear_scene, load, pickable_models, single_object_scenario};
use rayon::prelude::*;
use serde_json::json;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// A scene's outcome and whether it settled.
struct Trial<T> {
    outcome: T,
    settled: bool,
}

pub fn run(world: &Path, trials: u64, seed: u64, json: bool) -> anyhow::Result<()> {
    let (scn, work) = load(world)?;
    let started = Instant::now();
    let progress = super::output::Progress::new(trials * (1 + pickable_models(&scn).len() as u64), json);
    let clutter: Vec<Trial<Vec<ObjectPicks>>> = (0..trials)
        .into_par_iter()
        .map(|k| {
            let (scene, settled) = settle(&scn, seed + k);
            let objects = clear_scene(&scn, &work, &scene)?;
            let cleared = objects.iter().filter(|o| o.cleared()).count();
            let attempts: usize = objects.iter().map(|o| o.attempts.len()).sum();
            progress.step(format!(
                "clutter seed {}: {cleared} of {} cleared in {attempts} picks",
                seed + k,
                objects.len()
            ));
            Ok(Trial { outcome: objects, settled })
        })
        .collect::<anyhow::Result<_>>()?;
    let models = pickable_models(&scn);
    let jobs: Vec<(String, u64)> =
        models.iter().flat_map(|m| (0..trials).map(move |k| (m.clone(), seed + k))).collect();
    let single: Vec<Trial<PickOutcome>> = jobs
        .par_iter()
        .map(|(model, s)| {
            let one = single_object_scenario(&scn, model);
            let (scene, settled) = settle(&one, *s);
            let out = marvin::server::pick::PickCell::new(&one, &work, &scene)?.pick(1, *s)?;
            progress.step(format!("single {model} seed {s}: {} {}", out.result, out.detail.as_deref().unwrap_or("")));
            Ok(Trial { outcome: out, settled })
        })
        .collect::<anyhow::Result<_>>()?;
    progress.finish();
    let wall_s = started.elapsed().as_secs_f64();
    let objects: Vec<&ObjectPicks> = clutter.iter().flat_map(|t| &t.outcome).collect();
    let mut report = report(&objects, &single, &models, wall_s, clutter.iter().filter(|t| !t.settled).count());
    report["world"] = json!(scn.world.name);
    report["seeds"] = json!([seed, seed + trials - 1]);
    if json {
        return emit(&serde_json::to_string_pretty(&report)?);
    }
    print_summary(&report)
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
