//! `marvin pick`: settle a scene, pick one object from its true pose, report what happened.

use super::output::emit;
use marvin::engine::recording::{Recording, Sink};
use marvin::server::pick::{PickCell, PickOutcome, clear_cell, load, single_object_scenario};
use std::path::Path;
use std::time::Instant;

/// Picks `object`, or with `None` every object in turn.
pub fn run(
    world: &Path,
    object: Option<u32>,
    model: Option<&str>,
    seed: Option<u64>,
    json: bool,
    rerun: Option<&Path>,
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
    let mut cell = PickCell::new(&scn, &work, &scene)?;
    let mut recording = rerun.map(|path| Recording::start(&Sink::File(path.to_path_buf()))).transpose()?;
    if let Some(r) = recording.as_mut() {
        record_cell(r, &cell, 0)?;
    }
    let outcomes = match object {
        Some(id) => vec![cell.pick(id, seed)?],
        None => clear_cell(&mut cell, seed)?.into_iter().flat_map(|o| o.attempts).collect(),
    };
    let wall_s = started.elapsed().as_secs_f64();
    if let (Some(mut r), Some(path)) = (recording, rerun) {
        for out in &outcomes {
            r.text(&format!("object {} ({}): {}", out.object, out.model, out.result))?;
        }
        record_cell(&mut r, &cell, 1)?;
        r.finish()?;
        if !json {
            eprintln!("recorded the picks in {} (open it with `rerun {}`)", path.display(), path.display());
        }
    }
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
        emit(&format!(
            "  grasp {g}, fingers closed to {:.1} mm, fingertips {:.1} mm past its centre of mass",
            out.closed_opening_mm.unwrap_or(0.0),
            out.grip_past_com_mm.unwrap_or(f64::NAN)
        ))?;
    }
    emit(&format!(
        "  {:.2} s simulated, worst joint tracking error {:.2e} ({})",
        out.simulated_s,
        out.max_tracking_error,
        out.worst_tracking_step.as_deref().unwrap_or("-")
    ))
}

/// The cell as the simulation has it, for rerun: the table and bins, the objects, the arm; at
/// step 0 (before the picks) or 1 (after them).
fn record_cell(r: &mut Recording, cell: &PickCell, step: usize) -> anyhow::Result<()> {
    use marvin::protocol::{TruthReply, WirePose};
    r.at(step, cell.simulated_s);
    let scn = cell.scn;
    let world_from_base = cell.work.world_from_base;
    // The true left camera (as built), where the truth is seen from.
    let rig = sim::rig::as_built(&scn.world.cameras, &scn.world.effects(), scn.world.as_built_seed);
    let world_from_cam = rig.left.pinhole.world_from_cam;
    let truth = TruthReply {
        objects: cell.truth_objects(),
        tool_in_gripper: None,
        world_from_base: WirePose::new(None, &world_from_base),
        world_from_cam: WirePose::new(None, &world_from_cam),
        cam_from_base: WirePose::new(None, &(world_from_cam.inverse() * world_from_base)),
        unsettled: None,
    };
    if step == 0 {
        r.cell_layout(scn)?;
    }
    r.truth(&truth, &scn.library)?;
    r.arm(&cell.work.arm, &cell.arm.joints(&cell.cell), cell.arm.opening(&cell.cell))
}
