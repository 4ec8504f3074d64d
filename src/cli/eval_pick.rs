//! `marvin eval pick`: seeded physical picks, in clutter and one object at a time.

use super::output::emit;
use marvin::pick::{PickOutcome, clear_scene, load, pickable_models, single_object_scenario};
use rayon::prelude::*;
use sim::Scene;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

pub fn run(world: &Path, trials: u64, seed: u64, json: bool) -> anyhow::Result<()> {
    let (scn, work) = load(world)?;
    let started = Instant::now();
    let clutter: Vec<PickOutcome> = (0..trials)
        .into_par_iter()
        .map(|k| {
            let scene = Scene::settle(&scn, seed + k);
            let outcomes = clear_scene(&scn, &work, &scene)?;
            let placed = outcomes.iter().filter(|o| o.placed).count();
            eprintln!("clutter scene {}: {placed}/{} placed", seed + k, outcomes.len());
            Ok(outcomes)
        })
        .collect::<anyhow::Result<Vec<_>>>()?
        .into_iter()
        .flatten()
        .collect();
    let models = pickable_models(&scn);
    let jobs: Vec<(String, u64)> =
        models.iter().flat_map(|m| (0..trials).map(move |k| (m.clone(), seed + k))).collect();
    let single: Vec<PickOutcome> = jobs
        .par_iter()
        .map(|(model, s)| {
            let one = single_object_scenario(&scn, model);
            let scene = Scene::settle(&one, *s);
            let out = marvin::pick::PickCell::new(&one, &work, &scene)?.pick(1, *s)?;
            if !out.placed {
                eprintln!("single {model} seed {s}: {} ({})", out.result, out.detail.as_deref().unwrap_or(""));
            }
            Ok(out)
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let wall_s = started.elapsed().as_secs_f64();
    let rate = |v: &[&PickOutcome]| v.iter().filter(|o| o.placed).count() as f64 / v.len().max(1) as f64;
    let mut by_model = BTreeMap::new();
    for m in &models {
        let of: Vec<&PickOutcome> = single.iter().filter(|o| &o.model == m).collect();
        by_model.insert(m.clone(), rate(&of));
    }
    let mut failures: BTreeMap<String, usize> = BTreeMap::new();
    for o in clutter.iter().chain(&single).filter(|o| !o.placed) {
        *failures.entry(o.result.clone()).or_default() += 1;
    }
    let all_clutter: Vec<&PickOutcome> = clutter.iter().collect();
    let all_single: Vec<&PickOutcome> = single.iter().collect();
    let simulated_s: f64 = clutter.iter().chain(&single).map(|o| o.simulated_s).sum();
    let report = serde_json::json!({
        "success_rate": rate(&all_clutter),
        "single_success_rate": rate(&all_single),
        "single_by_model": by_model,
        "failures": failures,
        "picks": {"clutter": clutter.len(), "single": single.len()},
        "simulated_s": simulated_s,
        "wall_s": wall_s,
    });
    if json {
        return emit(&serde_json::to_string_pretty(&report)?);
    }
    emit(&format!(
        "clutter: {:.3} of {} picks placed; single objects: {:.3} of {} placed",
        rate(&all_clutter),
        clutter.len(),
        rate(&all_single),
        single.len()
    ))?;
    for (m, r) in &by_model {
        emit(&format!("  {m:<10} {r:.3}"))?;
    }
    emit(&format!("failures: {failures:?}"))?;
    emit(&format!("{simulated_s:.0} s simulated in {wall_s:.0} s"))
}
