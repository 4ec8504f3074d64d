//! `marvin calibrate`: hand-eye calibration through the robot server (in-process on loopback,
//! or `--connect`ed), written to a file the server takes (`marvin eval calibrate`, seeded
//! calibrations against the simulation's truth, is in [`super::eval_calibrate`]).

use super::output::emit;
use anyhow::Context;
use camera_calib::file::CamerasFile;
use hand_eye::HandEyeFile;
use marvin::engine::calibrate::{CalibrateConfig, Calibration, calibrate};
use marvin::engine::calibrate_cameras::CameraCalibration;
use marvin::engine::client::Client;
use marvin::server::{CellConfig, Server, ServerConfig};
use nalgebra::Isometry3;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The command's arguments.
pub struct CalibrateArgs {
    pub world: PathBuf,
    pub poses: usize,
    pub seed: Option<u64>,
    pub connect: Option<String>,
    pub out: PathBuf,
    pub json: bool,
    /// Where to record the calibration for rerun, if anywhere.
    pub rerun: Option<PathBuf>,
    /// A camera calibration file (`marvin calibrate cameras`).
    pub cameras: Option<PathBuf>,
}

/// The cameras of a camera calibration file, as vision takes them.
pub fn load_cameras(path: &Path) -> anyhow::Result<mesh::StereoCalibration> {
    Ok(camera_calib::file::CamerasFile::load(path)?.stereo_calibration())
}

/// What evaluation learns from the simulation (an in-process server only), after the fact.
#[derive(Debug, Clone, Default)]
pub struct Truth {
    pub cam_from_base: Option<Isometry3<f64>>,
    /// The flag in the gripper, from the physics, at each capture from the first sighting the
    /// calibration kept (those before a hand-in again are set aside), with the pose's index.
    pub flag_in_gripper: Vec<(usize, Isometry3<f64>)>,
    /// Why the cell's scene had not settled, if it had not.
    pub unsettled: Option<String>,
}

impl Truth {
    /// How far the flag moved in the jaws between the first and last sighting, mm.
    pub fn flag_creep_mm(&self) -> Option<f64> {
        let ((_, a), (_, b)) = (self.flag_in_gripper.first()?, self.flag_in_gripper.last()?);
        Some((a.translation.vector - b.translation.vector).norm() * 1e3)
    }

    /// How far the flag turned in the jaws between the first and last sighting, degrees.
    pub fn flag_turn_deg(&self) -> Option<f64> {
        let ((_, a), (_, b)) = (self.flag_in_gripper.first()?, self.flag_in_gripper.last()?);
        Some(a.rotation.angle_to(&b.rotation).to_degrees())
    }
}

/// A server for one calibration or run: the one at `connect`, or one started here on loopback
/// for the world and seed. A local server's socket does not serve the `truth` op: evaluation
/// reads the truth in-process ([`Cell::local`], [`Server::truth`]).
pub enum Cell {
    Remote(String),
    Local(Server),
}

impl Cell {
    pub fn start(world: &Path, seed: u64, connect: Option<&str>) -> anyhow::Result<Cell> {
        if let Some(addr) = connect {
            return Ok(Cell::Remote(addr.to_string()));
        }
        let cell = CellConfig {
            world: world.to_path_buf(),
            seed: Some(seed),
            cam_from_base: None,
            expose_truth: false,
            cameras: None,
        };
        Ok(Cell::Local(Server::start(ServerConfig::new(cell, "127.0.0.1:0".parse()?))?))
    }

    /// A greeted client, and the server's greeting.
    pub fn connect_greeted(&self) -> anyhow::Result<(Client, marvin::protocol::HelloReply)> {
        let addr = match self {
            Cell::Remote(a) => a.clone(),
            Cell::Local(s) => s.addr().to_string(),
        };
        let mut client = Client::connect(&addr, Duration::from_secs(10))?;
        let token = std::env::var("MARVIN_TOKEN").ok();
        let hello = client.hello(token.as_deref())?;
        Ok((client, hello))
    }

    /// The server started here, if it was: evaluation asks it for the truth in-process.
    pub fn local(&self) -> Option<&Server> {
        match self {
            Cell::Local(s) => Some(s),
            Cell::Remote(_) => None,
        }
    }

    pub fn stop(self) -> anyhow::Result<()> {
        if let Cell::Local(s) = self {
            s.stop();
            s.wait()?;
        }
        Ok(())
    }
}

/// One calibration on `cell` through `config`'s cameras, or (without them) the cameras the
/// server publishes or, failing that, measured first ([`super::cameras::cameras`]); with a
/// local cell, the truth evaluation needs. A camera calibration made here comes back too.
pub fn run_once(
    cell: &Cell,
    library: &mesh::Library,
    config: &CalibrateConfig,
    quiet: bool,
    progress: &mut dyn FnMut(&str),
) -> anyhow::Result<(Calibration, Truth, Option<CameraCalibration>)> {
    let (mut client, hello) = cell.connect_greeted()?;
    let (cameras, measured) =
        super::cameras::cameras(&mut client, &hello, library, config.cameras.as_ref(), config.seed, quiet, false)?;
    let config = &CalibrateConfig { cameras: Some(cameras), ..config.clone() };
    let mut truth = Truth::default();
    let local = cell.local();
    let mut after_capture = |_: &mut Client, k: usize| -> anyhow::Result<()> {
        if let Some(server) = local {
            let t = server.truth()?;
            if let Some(p) = t.tool_in_gripper {
                truth.flag_in_gripper.push((k, p.to_isometry("tool_in_gripper")?));
            }
            truth.cam_from_base = Some(t.cam_from_base.to_isometry("cam_from_base")?);
            truth.unsettled = t.unsettled;
        }
        Ok(())
    };
    let calibration = calibrate(&mut client, library, config, &mut after_capture, progress)?;
    client.bye()?;
    // Captures before the flag was handed in again held it otherwise.
    let first_kept = calibration.poses.iter().position(|p| p.cam_from_flag.is_some()).unwrap_or(0);
    truth.flag_in_gripper.retain(|(k, _)| *k >= first_kept);
    Ok((calibration, truth, measured))
}

fn pose_json(p: &Isometry3<f64>) -> Value {
    serde_json::to_value(hand_eye::PoseJson::from(p)).expect("a pose serialises")
}

/// Error of the solved `cam_from_base` against the truth: mm and degrees.
pub fn error_of(c: &Calibration, truth: &Truth) -> Option<(f64, f64)> {
    let t = truth.cam_from_base?;
    let s = &c.solution.cam_from_base;
    Some(((s.translation.vector - t.translation.vector).norm() * 1e3, s.rotation.angle_to(&t.rotation).to_degrees()))
}

pub fn run(args: CalibrateArgs) -> anyhow::Result<()> {
    let scn = sim::Scenario::load(&args.world)?;
    let seed = args.seed.unwrap_or(scn.world.seed);
    let cameras = args.cameras.as_deref().map(load_cameras).transpose()?;
    let config = CalibrateConfig { poses: args.poses, seed, cameras, ..CalibrateConfig::default() };
    if !args.json {
        eprintln!("calibrating: {} poses, seed {seed}", config.poses);
    }
    let cell = Cell::start(&args.world, seed, args.connect.as_deref())?;
    let quiet = args.json;
    let mut progress = |line: &str| {
        if !quiet {
            eprintln!("  {line}");
        }
    };
    let (calibration, truth, measured) = run_once(&cell, &scn.library, &config, quiet, &mut progress)?;
    cell.stop()?;
    let file = HandEyeFile::from_solution(&calibration.solution);
    file.save(&args.out)?;
    // Cameras measured on the way are kept beside the hand-eye file, for `--cameras` next time.
    let cameras_dir = args.out.parent().unwrap_or(Path::new(".")).to_path_buf();
    if let Some(m) = &measured {
        CamerasFile::from_solution(&m.solution, m.size)
            .save_all(&cameras_dir)
            .with_context(|| format!("writing the camera calibration in {}", cameras_dir.display()))?;
    }
    if let Some(path) = &args.rerun {
        record(path, &scn, &calibration, truth.cam_from_base.as_ref())?;
        if !args.json {
            eprintln!("recorded the calibration in {} (open it with `rerun {}`)", path.display(), path.display());
        }
    }
    let s = &calibration.solution;
    let error = error_of(&calibration, &truth);
    if args.json {
        let sightings: Vec<Value> = calibration
            .poses
            .iter()
            .filter(|p| p.base_from_gripper.is_some())
            .map(|p| {
                json!({
                    "base_from_gripper": p.base_from_gripper.as_ref().map(pose_json),
                    "cam_from_flag": p.cam_from_flag.as_ref().map(pose_json),
                    "used": p.used,
                    "note": p.note,
                })
            })
            .collect();
        let mut doc = json!({
            "sightings": sightings,
            "cam_from_base": pose_json(&s.cam_from_base),
            "gripper_from_flag": pose_json(&s.gripper_from_flag),
            "residual_mm_rms": s.residual_mm_rms,
            "residual_deg_rms": s.residual_deg_rms,
            "sigma": s.sigma,
            "out": args.out.display().to_string(),
            "cameras_out": measured.as_ref().map(|_| cameras_dir.join("cameras.json").display().to_string()),
        });
        if let (Some(t), Some((mm, deg))) = (truth.cam_from_base, error) {
            doc["truth"] = json!({
                "cam_from_base": pose_json(&t),
                // From the physics at the first sighting (it creeps: see flag_creep_mm).
                "gripper_from_flag": truth.flag_in_gripper.first().map(|(_, p)| pose_json(p)),
            });
            doc["error"] = json!({ "translation_mm": mm, "rotation_deg": deg });
            doc["flag_creep_mm"] = json!(truth.flag_creep_mm());
            doc["flag_turn_deg"] = json!(truth.flag_turn_deg());
        }
        return emit(&doc.to_string());
    }
    let used = s.used.iter().filter(|u| **u).count();
    emit(&format!(
        "{used} of {} poses used; residuals {:.3} mm, {:.3} deg RMS; sigma {:.3} mm, {:.4} deg",
        calibration.poses.len(),
        s.residual_mm_rms,
        s.residual_deg_rms,
        s.sigma.cam_from_base_mm,
        s.sigma.cam_from_base_deg
    ))?;
    if let Some((mm, deg)) = error {
        emit(&format!("against the simulation's truth: {mm:.3} mm, {deg:.4} deg"))?;
    }
    if let (Some(creep), Some(turn)) = (truth.flag_creep_mm(), truth.flag_turn_deg()) {
        emit(&format!(
            "the flag moved {creep:.3} mm and turned {turn:.3} deg in the jaws between the first and last sighting"
        ))?;
    }
    if measured.is_some() {
        emit(&format!("wrote the cameras it calibrated first in {}", cameras_dir.join("cameras.json").display()))?;
    }
    emit(&format!("wrote {}", args.out.display()))
}

/// The calibration recorded for rerun: its sightings, the solved camera (and the true one,
/// known locally), the cell's fixed parts, a log line per pose.
fn record(
    path: &Path,
    scn: &sim::Scenario,
    c: &Calibration,
    true_cam_from_base: Option<&Isometry3<f64>>,
) -> anyhow::Result<()> {
    let mut r =
        marvin::engine::recording::Recording::start(&marvin::engine::recording::Sink::File(path.to_path_buf()))?;
    r.at(0, 0.0);
    for (k, p) in c.poses.iter().enumerate() {
        r.text(&format!("pose {}/{}: {}", k + 1, c.poses.len(), p.note))?;
    }
    r.calibration(c)?;
    if let Some(t) = true_cam_from_base {
        r.true_camera(t)?;
    }
    r.cell_layout(scn)?;
    r.finish()
}
