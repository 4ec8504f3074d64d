//! `marvin`: the command line of the MARVIN rebuild: its arguments and which verb of
//! [`cli`] each runs.

mod cli;

use cli::{bench, calibrate, calibrate_cameras, edges, eval, locate, locate_pair, pick, render, run, serve, stereo};

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
    /// The main job: clear the table from what the cameras see.
    ///
    /// Starts the robot server for the world in-process on loopback (or uses the one at
    /// --connect) and talks to it only over the socket; calibrates the hand-eye transform first
    /// (or takes --hand-eye FILE); then cycles: the arm parks, the cameras capture, the front end
    /// and the matcher locate the parts, the highest reachable one is picked into the bin by the
    /// server; until nothing more is located. One line per cycle, a summary (with a server
    /// started here, the objects cleared against the simulation's truth, read afterwards), and
    /// the stage times beside the paper's Table 1.
    Run {
        world: PathBuf,
        /// Seed of the scene (default: the world file's).
        #[arg(long)]
        seed: Option<u64>,
        /// A running robot server (`marvin serve`) instead of one started here.
        #[arg(long)]
        connect: Option<String>,
        /// A hand-eye file (from `marvin calibrate`) instead of calibrating first.
        #[arg(long)]
        hand_eye: Option<PathBuf>,
        /// The cameras as `marvin calibrate cameras` measured them (its cameras.json), lenses
        /// included, instead of the calibration the captures carry.
        #[arg(long)]
        cameras: Option<PathBuf>,
        /// Pick cycles at most.
        #[arg(long, default_value_t = 40, value_parser = clap::value_parser!(u16).range(1..=1000))]
        max_cycles: u16,
        #[arg(long)]
        json: bool,
        /// Record the run for rerun in this file (open it with `rerun FILE.rrd`).
        #[arg(long, conflicts_with = "rerun_connect")]
        rerun: Option<PathBuf>,
        /// Stream the run to a running rerun viewer (its gRPC URL, default
        /// rerun+http://127.0.0.1:9876/proxy).
        #[arg(long, num_args = 0..=1, default_missing_value = "")]
        rerun_connect: Option<String>,
        /// Write each cycle's pair of images to this folder as the cameras sent them
        /// (cycle_NN_left.png, cycle_NN_right.png), to look at any cycle again with `marvin
        /// locate --left --right --cameras`.
        #[arg(long)]
        save_captures: Option<PathBuf>,
    },
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
        /// Render this many scenes, seeds `--seed` on, each in a folder of `--out` named by its
        /// seed: the folder of scenes `marvin eval pairs` reads.
        #[arg(long, requires = "seed", value_parser = clap::value_parser!(u64).range(1..=cli::args::MAX_COUNT))]
        scenes: Option<u64>,
    },
    /// Canny edges and edge strings of any image.
    ///
    /// Prints a summary, or with --json every edgel (`x`, `y` sub-pixel; `orientation` of the
    /// gradient in radians; `contrast` in grey levels per pixel) and every string (edgel indices
    /// in order).
    Edges {
        /// A grey (or colour, read as grey) image, e.g. out/render/left.png.
        image: PathBuf,
        /// Standard deviation of the Gaussian, pixels (0.3-10).
        #[arg(long, default_value_t = 1.0, value_parser = edges::parse_sigma, allow_negative_numbers = true)]
        sigma: f32,
        #[arg(long)]
        json: bool,
        /// Write the strings drawn over the image as a PNG.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// The vision front end on a stereo pair, rendered or real: Canny, edge strings,
    /// rectification, PMF stereo.
    ///
    /// Prints a summary, or with --json: `matches` (left edgel `x`, `y` in the left image and
    /// `disparity` in rectified pixels), `lines2d` (ends in left-image pixels), `lines3d` (ends
    /// `a`, `b` in metres in the `cam` frame, the left camera's, with depth sigmas) and
    /// per-stage `timings_ms`.
    Stereo {
        #[arg(long)]
        left: PathBuf,
        #[arg(long)]
        right: PathBuf,
        /// Calibration: a scene.json from `marvin render`, or a bare {left, right} file.
        #[arg(long, conflicts_with_all = ["rectified", "cameras"])]
        calib: Option<PathBuf>,
        /// The cameras as `marvin calibrate cameras` measured them (its cameras.json): edge
        /// locations are corrected for each lens's distortion before they are rectified.
        #[arg(long, conflicts_with = "rectified")]
        cameras: Option<PathBuf>,
        /// The images are already rectified (rows are epipolar lines); needs --disparity.
        #[arg(long, requires = "disparity")]
        rectified: bool,
        /// Disparity range MIN:MAX in pixels, for --rectified images.
        #[arg(long, value_parser = stereo::parse_range, allow_hyphen_values = true)]
        disparity: Option<(f32, f32)>,
        /// Horizontal slices processed in parallel and joined, as MARVIN's processors did (1: the
        /// whole image at once). Calibrated pairs only; rectified input runs whole.
        #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u16).range(1..=64))]
        slices: u16,
        #[arg(long)]
        json: bool,
        /// Folder for debug images: edges.png (left strings), matches.png (matched edgels
        /// coloured by disparity, blue far to red near).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Render a scene, run the front end and the model matcher; list the located objects with
    /// their errors against ground truth, the misses and the false reports. Or, with `--left L
    /// --right R --cameras FILE` and no world, any stereo pair: what was found, compared with a
    /// truth file only if `--truth` gives one. With no cell layout the matcher takes the table's
    /// top from the pair's own 3D lines (JSON `table_top`; a note says where, or that none was
    /// found), and sets apart the lines on it with soft edges as shadows or texture (JSON
    /// `lines3d_set_apart`, and a note).
    Locate {
        #[arg(required_unless_present = "left", conflicts_with_all = ["left", "right"])]
        world: Option<PathBuf>,
        /// The left image of a pair from any cameras (with --right and --cameras, no world).
        #[arg(long, requires_all = ["right", "cameras"])]
        left: Option<PathBuf>,
        #[arg(long, requires = "left")]
        right: Option<PathBuf>,
        /// Seed (default: the world file's).
        #[arg(long)]
        seed: Option<u64>,
        /// Only these models, comma-separated (default: every library model but the flag).
        #[arg(long, value_delimiter = ',')]
        models: Option<Vec<String>>,
        /// Print JSON: per located object its model, `cam_from_model`, the grasp in `cam`,
        /// support, image support, the 3D lines it rests on, and its errors; and the misses.
        #[arg(long)]
        json: bool,
        /// Folder for located.png: the located wireframes over the left image (false reports in
        /// red), and the missed objects' true wireframes dashed in white.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Record the scene for rerun in this file: both cameras and their images, the edgels,
        /// 2D and 3D lines, the located parts, the table and bins.
        #[arg(long)]
        rerun: Option<PathBuf>,
        /// Edgels as the blur places them, not deblurred (`CannyParams::deblur`; docs/TUNING.md,
        /// "Edgels beside narrow faces"), for comparison.
        #[arg(long)]
        no_deblur: bool,
        /// See through these measured cameras (`marvin calibrate cameras`' cameras.json, lenses
        /// included), placed where the left camera truly stands (evaluation takes the hand-eye
        /// calibration's part as known); without it, the cameras as the world file draws them.
        /// With --left/--right: the pair's cameras (cameras.json, or a scene.json).
        #[arg(long)]
        cameras: Option<PathBuf>,
        /// The hand-eye calibration (`marvin calibrate`'s file) that places the table, as `marvin
        /// run` places it; without it one is made first through the cameras vision sees by.
        #[arg(long, conflicts_with = "left")]
        hand_eye: Option<PathBuf>,
        /// With --left/--right: the scene's truth, a scene.json of `marvin render` (its objects'
        /// poses and the cameras as built): each report against the nearest object of its model
        /// (correct within 10 mm and 5 deg, under the model's symmetries), and the objects not
        /// located.
        #[arg(long, requires = "left")]
        truth: Option<PathBuf>,
    },
    /// Settle a scene and pick one object with the simulated arm, planned from the object's true
    /// pose, into the first bin; reports `placed` or what went wrong (`unplanned`, `miss`,
    /// `slip`, `drop`, `outside bin`, `wrong part`), judged from the physics (`src/server/judge.rs`).
    Pick {
        world: PathBuf,
        /// The object's id (1-based, as in scene.json).
        #[arg(long, required_unless_present = "all")]
        object: Option<u32>,
        /// Clear the table instead: pick every object in turn, the highest first.
        #[arg(long, conflicts_with = "object")]
        all: bool,
        /// Drop only this library model (object 1) over the clutter region instead of the
        /// world's clutter, as `eval pick` does for `single_success_rate`.
        #[arg(long)]
        model: Option<String>,
        /// Seed (default: the world file's).
        #[arg(long)]
        seed: Option<u64>,
        #[arg(long)]
        json: bool,
        /// Record the cell for rerun in this file: the table and bins, the objects and the arm
        /// before and after the picks, a log line per pick.
        #[arg(long)]
        rerun: Option<PathBuf>,
    },
    /// Host the simulated cell (world, arm, cameras) and the robot server behind a TCP socket
    /// speaking protocol v1 (docs/PROTOCOL.md), until Ctrl-C or an authorised `shutdown`.
    ///
    /// Prints `listening on ADDR` on stdout once the world has settled; logs every request on
    /// stderr (RUST_LOG filters).
    Serve {
        world: PathBuf,
        /// Seed (default: the world file's).
        #[arg(long)]
        seed: Option<u64>,
        /// Address to listen on; port 0 picks a free one. Off loopback a token is required.
        #[arg(long, default_value = "127.0.0.1:7878")]
        listen: std::net::SocketAddr,
        /// A file whose first line is the token every connection must give in `hello`
        /// (default: the MARVIN_TOKEN environment variable, if set).
        #[arg(long)]
        token_file: Option<PathBuf>,
        /// A hand-eye file (`cam_from_base`, as `marvin calibrate` writes it), so that
        /// `cam`-frame requests work from the start.
        #[arg(long)]
        hand_eye: Option<PathBuf>,
        /// The cameras as `marvin calibrate cameras` measured them (its cameras.json): what
        /// `capture` tells clients, lenses included, instead of the cameras as the world file
        /// draws them.
        #[arg(long)]
        cameras: Option<PathBuf>,
        /// Serve the `truth` op (the simulation's ground truth) for evaluation and tests.
        #[arg(long)]
        truth: bool,
        /// Close connections idle this long, seconds.
        #[arg(long, default_value_t = marvin::protocol::IDLE_TIMEOUT_S, value_parser = cli::args::seconds, allow_negative_numbers = true)]
        idle_timeout_s: f64,
    },
    /// Hand-eye calibration: the arm holds the calibration flag at poses over the workspace the
    /// cameras see, vision locates it, and least squares solves `cam_from_base` (and the flag
    /// in the gripper). Through the robot server: one started here on loopback for the world,
    /// or the one at --connect (MARVIN_TOKEN gives its token).
    ///
    /// Writes FILE (`cam_from_base`, `gripper_from_flag`, covariance, residuals, sightings used)
    /// for `marvin serve --hand-eye`. With --json prints the sightings, the result, and (with a
    /// server started here) the truth and the error against it, computed after the solve.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    Calibrate {
        /// `marvin calibrate cameras WORLD`: the cameras (see its --help).
        #[command(subcommand)]
        what: Option<CalibrateWhat>,
        #[arg(required = true)]
        world: Option<PathBuf>,
        /// Poses visited.
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u16).range(3..=500))]
        poses: u16,
        /// Seed of the scene and the poses (default: the world file's).
        #[arg(long)]
        seed: Option<u64>,
        /// A running robot server (`marvin serve`) instead of one started here.
        #[arg(long)]
        connect: Option<String>,
        #[arg(long, default_value = "out/hand_eye.json")]
        out: PathBuf,
        #[arg(long)]
        json: bool,
        /// Record the calibration for rerun in this file: the sightings, the solved camera (and
        /// the true one with a server started here), the table and bins.
        #[arg(long)]
        rerun: Option<PathBuf>,
        /// The cameras as `marvin calibrate cameras` measured them (its cameras.json), lenses
        /// included, instead of the calibration the captures carry.
        #[arg(long)]
        cameras: Option<PathBuf>,
    },
    /// Run seeded scenes through the pipeline and compare with ground truth.
    ///
    /// Every evaluation's JSON names its `world` and the `seeds` it ran (first and last). Seeds
    /// 1-9999 are for tuning, seeds from 10001 for reporting (see the README).
    Eval {
        #[command(subcommand)]
        what: eval::EvalTarget,
    },
    /// Measure how fast things run; prints medians.
    Bench {
        #[command(subcommand)]
        what: bench::BenchTarget,
    },
}

/// What `marvin calibrate` calibrates besides the hand-eye transform.
#[derive(Subcommand, Debug)]
enum CalibrateWhat {
    /// Camera calibration, as TINA did it with its tile: the arm holds the calibration board
    /// (10 x 7 squares of 18 mm) at tilted poses over the table, its corners are found in both
    /// images, and one least-squares adjustment solves both cameras' intrinsics and lens
    /// distortion and the right camera's pose in the left's. Through the robot server: one
    /// started here on loopback for the world, or the one at --connect.
    ///
    /// Writes OUT/cameras.json (with sigmas and covariance) and OUT/left.yaml, OUT/right.yaml
    /// (ROS camera_info, plumb_bob). With a server started here, prints the error against the
    /// cameras as built, computed after the solve.
    Cameras {
        world: PathBuf,
        /// Board poses planned; where their views do not determine the cameras (too few boards
        /// seen whole, or too little of the image covered), as many more are visited, twice at most.
        #[arg(long, default_value_t = 24, value_parser = clap::value_parser!(u16).range(3..=500))]
        poses: u16,
        /// Seed of the scene and the poses (default: the world file's).
        #[arg(long)]
        seed: Option<u64>,
        /// A running robot server (`marvin serve`) instead of one started here.
        #[arg(long)]
        connect: Option<String>,
        /// Folder for cameras.json, left.yaml and right.yaml.
        #[arg(long, default_value = "out/cameras")]
        out: PathBuf,
        #[arg(long)]
        json: bool,
        /// Write every view as lossless PNGs (viewNN_left.png, viewNN_right.png) with the
        /// board's geometry and the corners found in views.json, for any other tool.
        #[arg(long)]
        save_images: Option<PathBuf>,
        /// Record the calibration for rerun in this file: each view's images with the corners
        /// found, their reprojections and residuals; the cameras and the boards in 3D.
        #[arg(long)]
        rerun: Option<PathBuf>,
    },
}

fn main() -> std::process::ExitCode {
    // `RUST_LOG` (e.g. `marvin=debug`) logs what the robot server and the cell do, for every
    // command (`serve` logs at `info` without it).
    if let Ok(filter) = tracing_subscriber::EnvFilter::try_from_default_env() {
        let _ = tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).try_init();
    }
    let result = match Cli::parse().command {
        Command::Run {
            world,
            seed,
            connect,
            hand_eye,
            cameras,
            max_cycles,
            json,
            rerun,
            rerun_connect,
            save_captures,
        } => {
            use marvin::engine::recording::Sink;
            let rerun = match (rerun, rerun_connect) {
                (Some(file), _) => Some(Sink::File(file)),
                (None, Some(url)) => Some(Sink::Viewer(Some(url).filter(|u| !u.is_empty()))),
                (None, None) => None,
            };
            let max_cycles = max_cycles as usize;
            run::run(run::RunArgs { world, seed, connect, hand_eye, cameras, max_cycles, json, rerun, save_captures })
        }
        Command::Render { world, seed, out, scenes } => render::run(&world, seed, &out, scenes),
        Command::Edges { image, sigma, json, out } => edges::run(&image, sigma, json, out.as_deref()),
        Command::Stereo { left, right, calib, cameras, rectified, disparity, slices, json, out } => {
            stereo::geometry(calib.as_deref(), cameras.as_deref(), rectified, disparity)
                .and_then(|g| stereo::run(&left, &right, &g, slices as usize, json, out.as_deref()))
        }
        Command::Locate {
            world: None,
            left: Some(left),
            right: Some(right),
            cameras: Some(cameras),
            models,
            json,
            truth,
            ..
        } => locate_pair::run(locate_pair::PairArgs { left, right, cameras, models, json, truth }),
        Command::Locate { world, seed, models, json, out, rerun, no_deblur, cameras, hand_eye, .. } => {
            let canny = cli::scene::canny_params(!no_deblur);
            anyhow::Context::context(world, "a world file, or --left, --right and --cameras").and_then(|world| {
                locate::run(locate::LocateArgs { world, seed, models, json, out, rerun, cameras, hand_eye }, &canny)
            })
        }
        Command::Pick { world, object, all: _, model, seed, json, rerun } => {
            pick::run(&world, object, model.as_deref(), seed, json, rerun.as_deref())
        }
        Command::Serve { world, seed, listen, token_file, hand_eye, cameras, truth, idle_timeout_s } => {
            serve::run(serve::ServeArgs { world, seed, listen, token_file, hand_eye, cameras, truth, idle_timeout_s })
        }
        Command::Calibrate {
            what: Some(CalibrateWhat::Cameras { world, poses, seed, connect, out, json, save_images, rerun }),
            ..
        } => calibrate_cameras::run(calibrate_cameras::CamerasArgs {
            world,
            poses: poses as usize,
            seed,
            connect,
            out,
            json,
            save_images,
            rerun,
        }),
        Command::Calibrate { what: None, world, poses, seed, connect, out, json, rerun, cameras } => {
            let world = world.expect("clap requires the world without a subcommand");
            let poses = poses as usize;
            calibrate::run(calibrate::CalibrateArgs { world, poses, seed, connect, out, json, rerun, cameras })
        }
        Command::Eval { what } => eval::run(what),
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
