//! `marvin eval calibrate` and `eval calibrate cameras`: seeded calibrations, each on its own
//! scene, poses and sensor noise, against the simulation's truth; batched like `eval run`
//! (`--shard`, `--out`, `--resume`, `--jobs`, and `marvin eval merge` of the records), a record
//! per trial. A trial that fails is recorded as failed, with why.

use super::batch::{Batch, Runner, print_report};
use super::calibrate::{Cell, error_of, load_cameras};
use super::calibrate_cameras::TrueRig;
use anyhow::Context;
use marvin::engine::calibrate::CalibrateConfig;
use marvin::engine::calibrate_cameras::CameraCalibConfig;
use marvin::eval::batch::Record;
use marvin::eval::quantile;
use serde::{Deserialize, Serialize};
use serde_json::{Value, json};
use std::path::PathBuf;

/// What `eval calibrate` keeps of one hand-eye calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum HandEyeTrial {
    Solved {
        /// The solved `cam_from_base` against the true one.
        translation_mm: f64,
        rotation_deg: f64,
        /// How far the flag moved and turned in the jaws between the first and last sighting.
        flag_creep_mm: Option<f64>,
        flag_turn_deg: Option<f64>,
        unsettled: bool,
        sightings_used: usize,
        poses: usize,
    },
    Failed(String),
}

/// `marvin eval calibrate`: hand-eye calibrations through `cameras` (a calibration file) or
/// cameras measured once, on the range's first scene (every shard measures the same).
pub fn hand_eye(b: &Batch, poses: usize, cameras: Option<PathBuf>) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&b.world)?;
    let runner = Runner::open(b, "calibrate")?;
    // They stand where the world file puts them in every scene.
    let (measured, source) = match &cameras {
        Some(path) => (load_cameras(path)?, path.display().to_string()),
        None => {
            let cell = Cell::start(&b.world, b.seed, None)?;
            let (mut client, hello) = cell.connect_greeted()?;
            let (c, _) = super::cameras::cameras(&mut client, &hello, &scn.library, None, b.seed, true, false)?;
            client.bye()?;
            cell.stop()?;
            (c, format!("calibrated on seed {}", b.seed))
        }
    };
    let shared = json!({
        "world_name": scn.world.name, "poses": poses, "cameras": source,
        "cameras_digest": digest(&serde_json::to_string(&measured)?),
    });
    let trial = |s: u64| {
        let config = CalibrateConfig { poses, seed: s, cameras: Some(measured.clone()), ..CalibrateConfig::default() };
        let cell = Cell::start(&b.world, s, None)?;
        let outcome = super::calibrate::run_once(&cell, &scn.library, &config, true, &mut |_| {});
        cell.stop()?;
        let (trial, line) = match outcome {
            Ok((c, truth, _)) => {
                let (mm, deg) = error_of(&c, &truth).context("a local server gives the truth")?;
                let used = c.solution.used.iter().filter(|u| **u).count();
                let line = format!("{mm:.3} mm, {deg:.4} deg ({used} of {} poses used)", c.poses.len());
                let trial = HandEyeTrial::Solved {
                    translation_mm: mm,
                    rotation_deg: deg,
                    flag_creep_mm: truth.flag_creep_mm(),
                    flag_turn_deg: truth.flag_turn_deg(),
                    unsettled: truth.unsettled.is_some(),
                    sightings_used: used,
                    poses: c.poses.len(),
                };
                (trial, line)
            }
            Err(e) => (HandEyeTrial::Failed(format!("{e:#}")), format!("failed: {e:#}")),
        };
        Ok((serde_json::to_value(trial)?, line))
    };
    let records = runner.run(&shared, &trial)?;
    print_report(summarise_hand_eye(&records)?, b.shard, b.json)
}

/// The summary of `eval calibrate` records (sorted by seed), as one process over them prints it.
pub fn summarise_hand_eye(records: &[Record]) -> anyhow::Result<Value> {
    let first = records.first().context("no trials to summarise")?;
    let (mut t_err, mut r_err, mut creep, mut turn) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut used, mut total, mut failed, mut unsettled) = (0usize, 0usize, Vec::new(), 0usize);
    for r in records {
        let trial: HandEyeTrial = serde_json::from_value(r.scene.clone())
            .with_context(|| format!("seed {}: not an `eval calibrate` trial", r.seed))?;
        match trial {
            HandEyeTrial::Solved {
                translation_mm,
                rotation_deg,
                flag_creep_mm,
                flag_turn_deg,
                unsettled: u,
                sightings_used,
                poses,
            } => {
                t_err.push(translation_mm);
                r_err.push(rotation_deg);
                creep.extend(flag_creep_mm);
                turn.extend(flag_turn_deg);
                unsettled += usize::from(u);
                used += sightings_used;
                total += poses;
            }
            HandEyeTrial::Failed(why) => failed.push(json!({ "seed": r.seed, "error": why })),
        }
    }
    let q = quantile;
    let mut report = json!({
        "world": first.shared["world_name"],
        "seeds": first.range,
        "trials": records.len(),
        "cameras": first.shared["cameras"],
        "translation_err_mm_median": q(&t_err, 0.5),
        "translation_err_mm_p90": q(&t_err, 0.9),
        "rotation_err_deg_median": q(&r_err, 0.5),
        "rotation_err_deg_p90": q(&r_err, 0.9),
        "sightings_used_fraction": used as f64 / total.max(1) as f64,
        "flag_creep_mm_max": creep.iter().copied().fold(0.0, f64::max),
        "flag_creep_mm_median": q(&creep, 0.5),
        "flag_turn_deg_max": turn.iter().copied().fold(0.0, f64::max),
        "flag_turn_deg_median": q(&turn, 0.5),
        "failed": failed,
        "unsettled_scenes": unsettled,
        "version": first.version,
    });
    marvin::eval::add_intervals(&mut report, &[("sightings_used_fraction", used, total)]);
    Ok(report)
}

/// What `eval calibrate cameras` keeps of one camera calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum CamerasTrial {
    Solved {
        rms_px: f64,
        /// Against the cameras as built ([`TrueRig::errors`]).
        error: Value,
        views_used: usize,
        /// Views in which the board had left the jaws.
        board_lost: usize,
    },
    Failed(String),
}

/// `marvin eval calibrate cameras`.
pub fn cameras(b: &Batch, poses: usize) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&b.world)?;
    let runner = Runner::open(b, "calibrate-cameras")?;
    let truth = TrueRig::of(&scn.world);
    let shared = json!({ "world_name": scn.world.name, "poses": poses });
    let trial = |s: u64| {
        let config = CameraCalibConfig { poses, seed: s, ..CameraCalibConfig::default() };
        let cell = Cell::start(&b.world, s, None)?;
        let (trial, line) = match super::calibrate_cameras::run_once(cell, &scn.library, &config, false, &mut |_| {}) {
            Ok(c) => {
                let error = truth.errors(&c.solution, c.size);
                let views_used =
                    c.solution.views.iter().filter(|v| v.left_rms_px.is_some() || v.right_rms_px.is_some()).count();
                let board_lost = c.views.iter().filter(|v| v.note.contains("left the jaws")).count();
                let line = format!(
                    "{views_used} views, rms {:.3} px, baseline {:+.3} mm",
                    c.solution.rms_px, error["baseline_mm"]
                );
                (CamerasTrial::Solved { rms_px: c.solution.rms_px, error, views_used, board_lost }, line)
            }
            Err(e) => (CamerasTrial::Failed(format!("{e:#}")), format!("failed: {e:#}")),
        };
        Ok((serde_json::to_value(trial)?, line))
    };
    let records = runner.run(&shared, &trial)?;
    print_report(summarise_cameras(&records)?, b.shard, b.json)
}

/// The summary of `eval calibrate cameras` records (sorted by seed): per error its median and
/// 90th percentile over the trials (both cameras pooled for the intrinsics).
pub fn summarise_cameras(records: &[Record]) -> anyhow::Result<Value> {
    let first = records.first().context("no trials to summarise")?;
    let (mut errors, mut used, mut lost, mut failed) = (Vec::new(), Vec::new(), 0usize, Vec::new());
    for r in records {
        let trial: CamerasTrial = serde_json::from_value(r.scene.clone())
            .with_context(|| format!("seed {}: not an `eval calibrate cameras` trial", r.seed))?;
        match trial {
            CamerasTrial::Solved { rms_px, error, views_used, board_lost } => {
                used.push(views_used as f64);
                lost += board_lost;
                errors.push(json!({ "seed": r.seed, "rms_px": rms_px, "error": error }));
            }
            CamerasTrial::Failed(why) => failed.push(json!({ "seed": r.seed, "error": why })),
        }
    }
    let pooled = |keys: &[&str]| -> Vec<f64> {
        errors
            .iter()
            .flat_map(|t| ["left", "right"].map(|c| &t["error"][c]))
            .flat_map(|c| keys.iter().map(move |k| c[*k].as_f64().unwrap_or(f64::NAN).abs()))
            .collect()
    };
    let rig =
        |key: &str| -> Vec<f64> { errors.iter().map(|t| t["error"][key].as_f64().unwrap_or(f64::NAN).abs()).collect() };
    let rms: Vec<f64> = errors.iter().map(|t| t["rms_px"].as_f64().unwrap_or(f64::NAN)).collect();
    let both = |v: Vec<f64>| json!({ "median": quantile(&v, 0.5), "p90": quantile(&v, 0.9) });
    Ok(json!({
        "world": first.shared["world_name"],
        "seeds": first.range,
        "trials": records.len(),
        "f_rel": both(pooled(&["fx_rel", "fy_rel"])),
        "principal_point_px": both(pooled(&["cx_px", "cy_px"])),
        "distortion_field_px_max": both(pooled(&["distortion_px_max"])),
        "baseline_mm": both(rig("baseline_mm")),
        "right_position_mm": both(rig("right_position_mm")),
        "rotation_deg": both(rig("rotation_deg")),
        "rms_px": both(rms),
        "views_used_median": quantile(&used, 0.5),
        "board_lost_on_the_way": lost,
        "failed": failed,
        "trials_detail": errors,
        "version": first.version,
    }))
}

/// A short fingerprint of a text (FNV-1a, 64 bits): records made through different cameras
/// differ in it, and merge refuses to mix them.
fn digest(text: &str) -> String {
    let hash = text.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3));
    format!("{hash:016x}")
}
