//! `marvin`: the command line of the MARVIN rebuild.

mod bench;
mod render_cmd;

use clap::{Parser, Subcommand};
use std::path::PathBuf;

/// MARVIN rebuilt in Rust: a simulated stereo vision + pick-and-place cell.
#[derive(Parser)]
#[command(version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Settle a world's objects and render what both cameras see.
    ///
    /// Writes left.png and right.png (8-bit grey), depth_left.png and depth_right.png (16-bit,
    /// units of 0.1 mm along the optical axis, 0 = no surface), ids_left.png and ids_right.png
    /// (16-bit object ids, 0 = table, floor, bins), and scene.json (the calibration of both
    /// cameras and every object's ground-truth pose).
    Render {
        /// The world file, e.g. worlds/widgets.toml.
        world: PathBuf,
        /// Seed for clutter poses and sensor noise (default: the world file's `seed`).
        #[arg(long)]
        seed: Option<u64>,
        /// Output folder (created if missing).
        #[arg(long, default_value = "out/render")]
        out: PathBuf,
    },
    /// Measure how fast things run; prints medians.
    Bench {
        #[command(subcommand)]
        what: bench::BenchTarget,
    },
}

fn main() -> std::process::ExitCode {
    let result = match Cli::parse().command {
        Command::Render { world, seed, out } => render_cmd::run(&world, seed, &out),
        Command::Bench { what } => bench::run(what),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
