//! One run on a robot server, as `marvin run` and `marvin eval run` both make it: the cameras
//! (from a file, as the server publishes them, or calibrated first from the board), the hand-eye
//! transform (known, from a file, or calibrated next), then the pick cycles, recorded if asked;
//! and how a cycle's outcome is named. Evaluation watches through a [`Watcher`]; nothing the run
//! decides comes from it.

use super::calibrate::Cell;
use anyhow::Context;
use marvin::engine::calibrate::{CalibrateConfig, Calibration, calibrate};
use marvin::engine::client::Client;
use marvin::engine::recording::Recording;
use marvin::engine::run::{Cycle, RunConfig, RunEvent, RunReport};
use marvin::protocol::{CaptureReply, PickOutcomeKind, WirePose};
use nalgebra::Isometry3;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use vision::matcher::Located;

/// Where a run's hand-eye transform comes from.
pub enum HandEye {
    /// Calibrated at the start of the run.
    Calibrate,
    /// A calibration file.
    File(PathBuf),
    /// Known already (an evaluation calibrates once for all its scenes).
    Known(Isometry3<f64>),
}

/// Who watches a run from outside it: evaluation, reading the simulation in-process from the
/// server it started (never over the socket), and judging after the fact. Nothing the run
/// decides comes from it.
pub trait Watcher {
    /// The hand-eye transform is known (`calibration` is the run's own, if it calibrated).
    fn started(
        &mut self,
        cam_from_base: &Isometry3<f64>,
        calibration: Option<&Calibration>,
        recording: Option<&mut Recording>,
    ) -> anyhow::Result<()>;
    /// Just before cycle `cycle` picks `chosen`.
    fn before_pick(&mut self, cycle: usize, chosen: &Located) -> anyhow::Result<()>;
    /// The run is over.
    fn finished(&mut self, recording: Option<&mut Recording>) -> anyhow::Result<()>;
}

/// The hand-eye transform: known, from a file, or calibrated now.
pub fn hand_eye(
    client: &mut Client,
    library: &mesh::Library,
    source: &HandEye,
    seed: u64,
    quiet: bool,
    cameras: &mesh::StereoCalibration,
) -> anyhow::Result<(Isometry3<f64>, Option<Calibration>)> {
    if let HandEye::Known(x) = source {
        return Ok((*x, None));
    }
    if let HandEye::File(f) = source {
        let he = hand_eye::HandEyeFile::load(f)?;
        return Ok((he.cam_from_base.to_isometry(), None));
    }
    let config = CalibrateConfig { seed, cameras: Some(cameras.clone()), ..CalibrateConfig::default() };
    let mut progress = |line: &str| {
        if !quiet {
            eprintln!("  calibration {line}");
        }
    };
    let c = calibrate(client, library, &config, &mut |_, _| Ok(()), &mut progress).context("calibrating")?;
    if !quiet {
        for line in hand_eye_summary(&c.solution) {
            eprintln!("{line}");
        }
    }
    Ok((c.solution.cam_from_base, Some(c)))
}

/// What a hand-eye calibration says of itself: sightings used, residuals, sigmas, and a
/// warning when it is too uncertain to pick by.
pub fn hand_eye_summary(s: &hand_eye::Solution) -> Vec<String> {
    let used = s.used.iter().filter(|u| **u).count();
    let mut lines = vec![format!(
        "  hand-eye: {used} of {} sightings used; residuals {:.2} mm, {:.3} deg RMS; sigma {:.2} mm, {:.3} deg",
        s.used.len(),
        s.residual_mm_rms,
        s.residual_deg_rms,
        s.sigma.cam_from_base_mm,
        s.sigma.cam_from_base_deg
    )];
    if marvin::engine::calibrate::too_uncertain(s) {
        let (mm, deg) = (marvin::engine::calibrate::UNCERTAIN_MM, marvin::engine::calibrate::UNCERTAIN_DEG);
        lines.push(format!(
            "warning: the hand-eye calibration is uncertain (sigma over {mm} mm or {deg} deg) after every round of \
             poses: picks may miss; calibrate with more poses (`marvin calibrate --poses 60`) and run with --hand-eye"
        ));
    }
    lines
}

/// One run on `cell`, with the hand-eye transform from `source`; `cycle_line` hears of each
/// cycle; `recording`, if any, is given everything to record; each capture's pair is written to
/// `captures`, if given ([`save_capture`]); `watcher` watches.
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
    captures: Option<&Path>,
    watcher: &mut dyn Watcher,
) -> anyhow::Result<RunReport> {
    let library = &scn.library;
    let (mut client, hello) = cell.connect_greeted()?;
    let (cameras, measured) = super::cameras::cameras(
        &mut client,
        &hello,
        library,
        config.cameras.as_ref(),
        seed,
        quiet,
        recording.is_some(),
    )?;
    let (cam_from_base, calibration) = hand_eye(&mut client, library, source, seed, quiet, &cameras)?;
    let config = &RunConfig { cameras: Some(cameras), ..config.clone() };
    // The arm as the recording draws it, from the world file's URDF.
    let arm = match recording.is_some() {
        true => Some(marvin::server::pick::Workcell::new(scn)?.arm),
        false => None,
    };
    if let Some(r) = recording.as_deref_mut() {
        if let Some(m) = &measured {
            r.camera_calibration(m)?;
        }
        match &calibration {
            Some(c) => r.calibration(c)?,
            None => r.calibration_known(&cam_from_base)?,
        }
        r.bins(&hello.bin_boxes)?;
        r.cell_layout(scn)?;
    }
    client.set_hand_eye(WirePose::new(None, &cam_from_base))?;
    watcher.started(&cam_from_base, calibration.as_ref(), recording.as_deref_mut())?;
    let mut sim_time = 0.0;
    let mut observe = |event: RunEvent<'_>| -> anyhow::Result<()> {
        match event {
            RunEvent::Captured { cycle, capture, pair, front_end } => {
                sim_time = capture.sim_time_s;
                if let Some(dir) = captures {
                    save_capture(dir, cycle, capture)?;
                }
                if let Some(r) = recording.as_deref_mut() {
                    r.at(cycle, sim_time);
                    r.capture(capture, pair, front_end)?;
                }
            }
            RunEvent::Located { located, in_doubt, .. } => {
                if let Some(r) = recording.as_deref_mut() {
                    r.located(located, in_doubt, library)?;
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
    let mut before_pick = |_: &mut Client, k: usize, l: &Located| watcher.before_pick(k, l);
    let report =
        marvin::engine::run::run(&mut client, library, config, &cam_from_base, &mut before_pick, &mut observe)?;
    if let Some(r) = recording.as_deref_mut() {
        r.at(report.cycles.len(), sim_time);
    }
    watcher.finished(recording)?;
    client.bye()?;
    Ok(report)
}

/// Writes cycle `cycle`'s pair as the cameras sent it (`cycle_NN_left.png`, `cycle_NN_right.png`,
/// NN counted from 1 as the cycle lines count), so that `marvin locate --left --right --cameras`
/// can look at any cycle again.
pub fn save_capture(dir: &Path, cycle: usize, capture: &CaptureReply) -> anyhow::Result<()> {
    use base64::Engine;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (side, b64) in [("left", &capture.left_png_b64), ("right", &capture.right_png_b64)] {
        let png = base64::engine::general_purpose::STANDARD
            .decode(b64)
            .with_context(|| format!("cycle {}: the {side} image is not base64", cycle + 1))?;
        let path = dir.join(format!("cycle_{:02}_{side}.png", cycle + 1));
        std::fs::write(&path, png).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
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

#[cfg(test)]
mod tests {
    use super::hand_eye_summary;

    fn solution(mm: f64, deg: f64) -> hand_eye::solve::Solution {
        hand_eye::solve::Solution {
            cam_from_base: nalgebra::Isometry3::identity(),
            gripper_from_flag: nalgebra::Isometry3::identity(),
            covariance: nalgebra::SMatrix::zeros(),
            sigma: hand_eye::solve::Sigmas {
                cam_from_base_deg: deg,
                cam_from_base_mm: mm,
                gripper_from_flag_deg: 0.0,
                gripper_from_flag_mm: 0.0,
            },
            residual_mm_rms: 0.1,
            residual_deg_rms: 0.01,
            used: vec![true, true, false],
            dropped: Vec::new(),
        }
    }

    /// Realistic tuning seed 3's calibration (sigma 10.6 mm, 1.5 deg; 4.9 mm / 2.2 deg off) is
    /// warned of; seed 1's (0.71 mm, 0.097 deg) is not.
    #[test]
    fn an_uncertain_hand_eye_calibration_is_warned_of() {
        let warned = |mm, deg| hand_eye_summary(&solution(mm, deg)).iter().any(|l| l.starts_with("warning"));
        assert!(warned(10.58, 1.534) && warned(0.5, 0.5) && warned(4.0, 0.05));
        assert!(!warned(0.71, 0.097));
        assert!(hand_eye_summary(&solution(0.71, 0.097))[0].contains("2 of 3 sightings used"));
    }
}
