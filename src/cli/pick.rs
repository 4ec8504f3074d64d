//! `marvin pick`: settle a scene, pick one object from its true pose, report what happened.

use super::output::emit;
use marvin::pick::{PickCell, PickOutcome, clear_scene, load, single_object_scenario};
use std::path::Path;
use std::time::Instant;

/// Picks `object`, or with `None` every object in turn.
pub fn run(
    world: &Path,
    object: Option<u32>,
    model: Option<&str>,
    seed: Option<u64>,
    json: bool,
) -> anyhow::Result<()> {
    let (mut scn, work) = load(world)?;
    if let Some(model) = model {
        if scn.library.get(model).is_none() {
            let known: Vec<&str> = scn.library.names().collect();
            anyhow::bail!("no model `{model}` in the library (it has: {})", known.join(", "));
        }
        scn = single_object_scenario(&scn, model);
    }
    let seed = seed.unwrap_or(scn.world.seed);
    let (scene, _) = super::output::settle(&scn, seed);
    let started = Instant::now();
    let outcomes = match object {
        Some(id) => vec![PickCell::new(&scn, &work, &scene)?.pick(id, seed)?],
        None => clear_scene(&scn, &work, &scene)?.into_iter().flat_map(|o| o.attempts).collect(),
    };
    let wall_s = started.elapsed().as_secs_f64();
    if json {
        let mut v = serde_json::json!({ "picks": outcomes, "wall_s": wall_s });
        v["placed"] = serde_json::json!(outcomes.iter().filter(|o| o.placed).count());
        return emit(&serde_json::to_string_pretty(&v)?);
    }
    let simulated: f64 = outcomes.iter().map(|o| o.simulated_s).sum();
    for out in &outcomes {
        report(out)?;
    }
    emit(&format!(
        "{} of {} placed; {simulated:.2} s simulated in {wall_s:.2} s ({:.1}x real time)",
        outcomes.iter().filter(|o| o.placed).count(),
        outcomes.len(),
        simulated / wall_s
    ))
}

fn report(out: &PickOutcome) -> anyhow::Result<()> {
    emit(&format!("object {} ({}): {}", out.object, out.model, out.result))?;
    if let Some(d) = &out.detail {
        emit(&format!("  {d}"))?;
    }
    if let Some(g) = out.grasp {
        emit(&format!("  grasp {g}, fingers closed to {:.1} mm", out.closed_opening_mm.unwrap_or(0.0)))?;
    }
    emit(&format!(
        "  {:.2} s simulated, worst joint tracking error {:.2e} ({})",
        out.simulated_s,
        out.max_tracking_error,
        out.worst_tracking_step.as_deref().unwrap_or("-")
    ))
}
