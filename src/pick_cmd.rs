//! `marvin pick`: settle a scene, pick one object from its true pose, report what happened.

use marvin::pick::{PickCell, load};
use sim::Scene;
use std::path::Path;
use std::time::Instant;

pub fn run(world: &Path, object: u32, seed: Option<u64>, json: bool) -> anyhow::Result<()> {
    let (scn, work) = load(world)?;
    let seed = seed.unwrap_or(scn.world.seed);
    let scene = Scene::settle(&scn, seed);
    let started = Instant::now();
    let mut cell = PickCell::new(&scn, &work, &scene)?;
    let out = cell.pick(object, seed)?;
    let wall_s = started.elapsed().as_secs_f64();
    if json {
        let mut v = serde_json::to_value(&out)?;
        v["wall_s"] = serde_json::json!(wall_s);
        return crate::emit(&serde_json::to_string_pretty(&v)?);
    }
    crate::emit(&format!("object {} ({}): {}", out.object, out.model, out.result))?;
    if let Some(d) = &out.detail {
        crate::emit(&format!("  {d}"))?;
    }
    if let Some(g) = out.grasp {
        crate::emit(&format!("  grasp {g}, fingers closed to {:.1} mm", out.closed_opening_mm.unwrap_or(0.0)))?;
    }
    crate::emit(&format!(
        "  {:.2} s simulated in {:.2} s ({:.1}x real time), worst joint tracking error {:.2e} ({})",
        out.simulated_s,
        wall_s,
        out.simulated_s / wall_s,
        out.max_tracking_error,
        out.worst_tracking_step.as_deref().unwrap_or("-")
    ))
}
