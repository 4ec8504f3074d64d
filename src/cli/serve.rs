//! `marvin serve`: the simulated cell and the robot server behind a TCP socket, until Ctrl-C or
//! an authorised `shutdown`.

use anyhow::{Context, bail};
use marvin::protocol::WirePose;
use marvin::server::{CellConfig, Server, ServerConfig};
use nalgebra::Isometry3;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The command's arguments.
pub struct ServeArgs {
    pub world: PathBuf,
    pub seed: Option<u64>,
    pub listen: SocketAddr,
    pub token_file: Option<PathBuf>,
    pub hand_eye: Option<PathBuf>,
    /// A camera calibration file (`marvin calibrate cameras`) for `capture` to tell clients.
    pub cameras: Option<PathBuf>,
    pub truth: bool,
    pub idle_timeout_s: f64,
}

pub fn run(args: ServeArgs) -> anyhow::Result<()> {
    init_logging();
    if !(args.idle_timeout_s.is_finite() && args.idle_timeout_s > 0.0) {
        bail!("--idle-timeout-s must be a positive number of seconds, got {}", args.idle_timeout_s);
    }
    let cell = CellConfig {
        world: args.world.clone(),
        seed: args.seed,
        cam_from_base: args.hand_eye.as_deref().map(load_hand_eye).transpose()?,
        expose_truth: args.truth,
        cameras: args.cameras.as_deref().map(super::calibrate::load_cameras).transpose()?,
    };
    let mut config = ServerConfig::new(cell, args.listen);
    config.token = token(args.token_file.as_deref())?;
    config.idle_timeout = Duration::from_secs_f64(args.idle_timeout_s);
    config.stop_on_ctrl_c = true;
    eprintln!("settling {} ...", args.world.display());
    let server = Server::start(config)?;
    // The address on stdout, alone on its line, for whoever started the server to read.
    super::output::emit(&format!("listening on {}", server.addr()))?;
    server.wait()?;
    eprintln!("stopped");
    Ok(())
}

/// Structured logs of every request on stderr (`RUST_LOG` filters; `info` by default).
fn init_logging() {
    let filter = tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into());
    let ansi = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let _ = tracing_subscriber::fmt().with_env_filter(filter).with_ansi(ansi).with_writer(std::io::stderr).try_init();
}

/// The token: the first line of `--token-file`, else `MARVIN_TOKEN`, else none.
fn token(file: Option<&Path>) -> anyhow::Result<Option<String>> {
    let token = match file {
        Some(f) => {
            let text =
                std::fs::read_to_string(f).with_context(|| format!("{}: cannot read the token file", f.display()))?;
            let t = text.lines().next().unwrap_or("").trim().to_string();
            if t.is_empty() {
                bail!("{}: the token file is empty", f.display());
            }
            Some(t)
        }
        None => std::env::var("MARVIN_TOKEN").ok().map(|t| t.trim().to_string()).filter(|t| !t.is_empty()),
    };
    Ok(token)
}

/// `cam_from_base` from a hand-eye file (as `marvin calibrate` writes it).
pub fn load_hand_eye(path: &Path) -> anyhow::Result<Isometry3<f64>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("{}: cannot read the hand-eye file", path.display()))?;
    let doc: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    let field = doc.get("cam_from_base").with_context(|| format!("{}: no field `cam_from_base`", path.display()))?;
    let pose: WirePose = serde_json::from_value(field.clone())
        .with_context(|| format!("{}: field `cam_from_base` is not a pose", path.display()))?;
    pose.to_isometry("cam_from_base").with_context(|| format!("{}", path.display()))
}
