//! `marvin bench`: medians of repeated runs. Never a pass/fail test: the machines are shared.

use super::output::emit;
use clap::{Args, Subcommand};
use sim::{Scenario, Scene};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand)]
pub enum BenchTarget {
    /// Median time to render the stereo pair of the default scene (images, depth and id maps).
    Render(BenchArgs),
    /// Median times of the vision front end on the default scene, with the cell's table known as
    /// `marvin run` knows it (the disparity search over it, its soft lines set apart).
    ///
    /// `canny`: Canny on one 512x512 image, one thread. `front_end`: the whole front end on the
    /// stereo pair (both Cannys, strings, rectification, PMF, 2D and 3D lines) in 8 slices and
    /// joined, on all cores; `slices` and `join` its two parts. `front_end_whole`: the same
    /// without slicing (`--slices 1`), with its stages `strings`, `rectify`, `pmf`, `geom2d`,
    /// `geom3d`; `sliced_canny` ... `sliced_geom3d` are the sliced run's stages, processor
    /// time summed over the 8 slices (Canny on each slice's own rasters, the rest with its halo). `image_evidence`: laying out the left edgels for verification. `match`: the
    /// model matcher (every library model but the flag) on the front end's 3D lines, verified
    /// against the left edgels. `vision_cycle`: stereo pair in, located
    /// objects out (the sliced front end, then the matcher).
    Vision(BenchArgs),
    /// Simulation speed of the arm at work among 10 objects: the default world's clutter plus
    /// another block, L-bracket and T-piece, cleared by picking (`marvin pick --all`), one
    /// thread. `realtime_factor`: simulated seconds per wall-clock second, median over `--runs`
    /// seeded scenes.
    Physics(PhysicsArgs),
    /// The robot server over loopback, started in-process on the default world.
    /// `status_p50_ms`, `status_p99_ms`: round trips of `status` (`--runs` of them, after 50 to
    /// warm up). `pick_plan_ms`: the server's planning time of a pick (inverse kinematics and
    /// paths, `plan_only`), median over every object of the scene planned from its true pose.
    Server(ServerBenchArgs),
}

#[derive(Args)]
pub struct ServerBenchArgs {
    #[arg(long, default_value = "worlds/widgets.toml")]
    world: PathBuf,
    /// `status` round trips timed.
    #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
    runs: u64,
    /// Print JSON: `{"server": {"status_p50_ms": X, "status_p99_ms": Y, "pick_plan_ms": Z, ...}}`.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct PhysicsArgs {
    #[arg(long, default_value = "worlds/widgets.toml")]
    world: PathBuf,
    /// Scenes cleared (seeds 1..=runs).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
    runs: u64,
    /// Print JSON: `{"physics": {"realtime_factor": X, ...}}`.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
pub struct BenchArgs {
    #[arg(long, default_value = "worlds/widgets.toml")]
    world: PathBuf,
    /// Timed repetitions.
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
    runs: u64,
    /// Print JSON: `{"<stage>": {"median_ms": X}, ...}`.
    #[arg(long)]
    json: bool,
    /// (vision) Also print the stages in the rows of the paper's Table 1, beside its figures,
    /// with the speed-up and the slices' parallel efficiency (`{"table1": [...]}` with --json).
    #[arg(long)]
    table1: bool,
    /// (vision) See through these measured cameras (`marvin calibrate cameras`' cameras.json,
    /// placed where the left camera truly stands, as `marvin eval vision --cameras` places
    /// them) instead of the world file's: the realistic cell's cameras differ from its file.
    #[arg(long)]
    cameras: Option<PathBuf>,
}

/// Median of `runs` timings of `f`, in milliseconds, after one warm-up run.
pub fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut ms: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    ms[ms.len() / 2]
}

/// A settled default scene and its calibration, which every benchmark starts from.
struct Setup {
    scn: Scenario,
    scene: Scene,
    calib: mesh::StereoCalibration,
}

fn setup(world: &std::path::Path) -> anyhow::Result<Setup> {
    let scn = Scenario::load(world)?;
    let scene = Scene::settle(&scn, scn.world.seed);
    let calib = sim::imaging::Imaging::new(&scn.world).nominal;
    Ok(Setup { scn, scene, calib })
}

fn report(args: &BenchArgs, results: &[(&str, f64)], what: &str) -> anyhow::Result<()> {
    if args.json {
        let map: serde_json::Map<String, serde_json::Value> =
            results.iter().map(|(k, v)| (k.to_string(), serde_json::json!({ "median_ms": v }))).collect();
        emit(&serde_json::Value::Object(map).to_string())
    } else {
        for (k, v) in results {
            emit(&format!("{k}: {v:.3} ms (median of {}; {what})", args.runs))?;
        }
        Ok(())
    }
}

/// The scenario with three more objects in its clutter (10 in the default world).
/// Each front-end stage's times over repeated runs.
#[derive(Default)]
struct StageTimes(std::collections::BTreeMap<&'static str, Vec<f64>>);

impl StageTimes {
    fn add(&mut self, timings_ms: &[(&'static str, f64)]) {
        for (name, ms) in timings_ms {
            self.0.entry(name).or_default().push(*ms);
        }
    }

    fn median(&mut self, name: &str) -> f64 {
        let v = self.0.get_mut(name).expect("every run times every stage");
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }
}

fn ten_objects(mut scn: Scenario) -> Scenario {
    if let Some(clutter) = &mut scn.world.clutter {
        for model in ["block", "l_bracket", "t_piece"] {
            clutter.objects.push(sim::world::ClutterItem { model: model.into(), count: 1 });
        }
    }
    scn
}

fn physics(args: &PhysicsArgs) -> anyhow::Result<()> {
    let (scn, work) = marvin::server::pick::load(&args.world)?;
    let scn = ten_objects(scn);
    let mut factors = Vec::new();
    let (mut simulated, mut wall, mut placed, mut picks) = (0.0, 0.0, 0, 0);
    for seed in 1..=args.runs.max(1) {
        let scene = Scene::settle(&scn, seed);
        let started = Instant::now();
        let objects = marvin::server::pick::clear_scene(&scn, &work, &scene)?;
        let w = started.elapsed().as_secs_f64();
        let outcomes: Vec<_> = objects.iter().flat_map(|o| &o.attempts).collect();
        let s: f64 = outcomes.iter().map(|o| o.simulated_s).sum();
        factors.push(s / w);
        (simulated, wall) = (simulated + s, wall + w);
        placed += outcomes.iter().filter(|o| o.placed).count();
        picks += outcomes.len();
    }
    factors.sort_by(f64::total_cmp);
    let median = factors[factors.len() / 2];
    if args.json {
        let v = serde_json::json!({ "physics": {
            "realtime_factor": median,
            "objects": scene_size(&scn),
            "simulated_s": simulated,
            "wall_s": wall,
            "placed": placed,
            "picks": picks,
        }});
        return emit(&v.to_string());
    }
    emit(&format!(
        "physics: realtime factor {median:.1} (median of {} scenes of {} objects cleared; {placed}/{picks} placed, {simulated:.0} s simulated in {wall:.1} s)",
        factors.len(),
        scene_size(&scn)
    ))
}

fn scene_size(scn: &Scenario) -> usize {
    scn.world.objects.len() + scn.world.clutter.as_ref().map_or(0, |c| c.objects.iter().map(|o| o.count as usize).sum())
}

pub fn run(target: BenchTarget) -> anyhow::Result<()> {
    match target {
        BenchTarget::Physics(args) => physics(&args),
        BenchTarget::Server(args) => server(&args),
        BenchTarget::Render(args) => render(&args),
        BenchTarget::Vision(args) => vision(&args),
    }
}

/// `marvin bench render`: the stereo pair as the world's preset draws it (`render`), as the
/// ideal preset draws it (`render_ideal`), and the realistic preset's shadow maps alone
/// (`shadow_maps`, part of `render`).
fn render(args: &BenchArgs) -> anyhow::Result<()> {
    let s = setup(&args.world)?;
    let seed = s.scn.world.seed;
    let timed = |world: &sim::WorldFile| {
        let imaging = sim::imaging::Imaging::new(world);
        median_ms(args.runs as usize, || {
            let rs = s.scene.render_scene(&s.scn.library, &imaging);
            std::hint::black_box(imaging.render_stereo(&rs, seed));
        })
    };
    let mut ideal = s.scn.world.clone();
    ideal.realism = sim::realism::Preset::Ideal;
    ideal.effects = Default::default();
    let imaging = sim::imaging::Imaging::new(&s.scn.world);
    let rs = s.scene.render_scene(&s.scn.library, &imaging);
    let corners = rs.corners();
    let shadow_maps = median_ms(args.runs as usize, || {
        std::hint::black_box(sim::lighting::Lighting::new(&imaging.lamps, imaging.light, &imaging.effects, &corners));
    });
    let results = [("render", timed(&s.scn.world)), ("render_ideal", timed(&ideal)), ("shadow_maps", shadow_maps)];
    let what = format!(
        "stereo pair of {} ({:?} preset), {} threads",
        args.world.display(),
        s.scn.world.realism,
        rayon::current_num_threads()
    );
    report(args, &results, &what)
}

/// `marvin bench vision`: the front end's stages, then the matcher and the whole cycle.
fn vision(args: &BenchArgs) -> anyhow::Result<()> {
    let s = setup(&args.world)?;
    // The pair as the world's preset forms it; vision given the world file's calibration, or
    // the measured cameras.
    let imaging = sim::imaging::Imaging::new(&s.scn.world);
    let calib = match &args.cameras {
        Some(path) => super::scene::eval_cameras(&imaging, Some(path))?.vision,
        None => s.calib.clone(),
    };
    let (l, r) = imaging.render_stereo(&s.scene.render_scene(&s.scn.library, &imaging), s.scn.world.seed);
    let left = vision::GreyImage::new(l.width, l.height, l.image).expect("a rendered frame is whole");
    let right = vision::GreyImage::new(r.width, r.height, r.image).expect("a rendered frame is whole");
    let params = vision::CannyParams::default();
    // The cell's table, as `marvin run` has it from the hand-eye calibration (here the world's
    // top, where the calibration's left camera stands): the front end searches disparities
    // over the table and sets its soft lines apart, and the matcher rests parts on it.
    let cam_from_table = calib.left.cam_from_world();
    let workspace = marvin::engine::perception::workspace(Some(&cam_from_table));
    // Buffers reused from run to run, as a pipeline seeing frame after frame does.
    let (mut ws, mut edges) = (vision::front_end::canny::CannyWorkspace::default(), vision::EdgeMap::default());
    let canny = median_ms(args.runs as usize, || {
        ws.run(&left, &params, &mut edges);
        std::hint::black_box(&edges);
    });
    let mut whole_stages = StageTimes::default();
    let whole = median_ms(args.runs as usize, || {
        whole_stages.add(&marvin::front_end::run(&left, &right, &calib, &workspace, &params).timings_ms);
    });
    let mut sliced_stages = StageTimes::default();
    let sliced = median_ms(args.runs as usize, || {
        sliced_stages
            .add(&vision::front_end::slices::run_sliced(&left, &right, &calib, &workspace, &params, 8).timings_ms);
    });
    let mut results = vec![("canny", canny)];
    for name in ["strings", "rectify", "pmf", "geom2d", "geom3d"] {
        results.push((name, whole_stages.median(name)));
    }
    for (name, key) in [
        ("canny", "sliced_canny"),
        ("strings", "sliced_strings"),
        ("rectify", "sliced_rectify"),
        ("pmf", "sliced_pmf"),
        ("geom2d", "sliced_geom2d"),
        ("geom3d", "sliced_geom3d"),
        ("slices", "slices"),
        ("join", "join"),
    ] {
        results.push((key, sliced_stages.median(name)));
    }
    results.push(("front_end", sliced));
    results.push(("front_end_whole", whole));
    // The matcher: every library model but the flag on the front end's 3D lines, with the
    // left image's edgels for verification; and the whole cycle, stereo pair in, located
    // objects out.
    let models = super::scene::matcher_models(&s.scn.library, None);
    let mp = marvin::engine::perception::part_params(Some(&cam_from_table));
    let fe = vision::front_end::slices::run_sliced(&left, &right, &calib, &workspace, &params, 8);
    let lines: Vec<vision::matcher::Seg> =
        fe.lines3d.iter().map(|l| vision::matcher::Seg::new(l.start(), l.end())).collect();
    let evidence = vision::matcher::verify::ImageEvidence::of_pair(&calib, &fe);
    let image_evidence = median_ms(args.runs as usize, || {
        std::hint::black_box(vision::matcher::verify::ImageEvidence::of_pair(&calib, &fe));
    });
    let matching = median_ms(args.runs as usize, || {
        std::hint::black_box(vision::matcher::locate_all(&models, &lines, &mp, Some(&evidence)));
    });
    let cycle = median_ms(args.runs as usize, || {
        let fe = vision::front_end::slices::run_sliced(&left, &right, &calib, &workspace, &params, 8);
        let lines: Vec<vision::matcher::Seg> =
            fe.lines3d.iter().map(|l| vision::matcher::Seg::new(l.start(), l.end())).collect();
        let evidence = vision::matcher::verify::ImageEvidence::of_pair(&calib, &fe);
        std::hint::black_box(vision::matcher::locate_all(&models, &lines, &mp, Some(&evidence)));
    });
    results.push(("image_evidence", image_evidence));
    results.push(("match", matching));
    results.push(("vision_cycle", cycle));
    let seen = args.cameras.as_ref().map_or(String::new(), |c| format!(" through {}", c.display()));
    let what =
        format!("{}{seen}; canny one thread, the rest {} threads", args.world.display(), rayon::current_num_threads());
    if args.table1 {
        return table1(args, &results, &mut sliced_stages);
    }
    report(args, &results, &what)
}

/// The vision medians in the rows of the paper's Table 1 (as `marvin run` prints them, without
/// the capture, which a bench does not make).
fn table1(args: &BenchArgs, results: &[(&str, f64)], sliced: &mut StageTimes) -> anyhow::Result<()> {
    let named = |k: &str| results.iter().find(|(n, _)| *n == k).map_or(0.0, |(_, v)| *v);
    let mut timings_ms: Vec<(&'static str, f64)> =
        ["canny", "strings", "rectify", "pmf", "geom2d", "geom3d", "slices", "join"]
            .iter()
            .map(|&n| (n, sliced.median(n)))
            .collect();
    timings_ms.push(("match", named("match")));
    let (rows, efficiency) = marvin::engine::run::table1(&[marvin::engine::run::Cycle::timed(timings_ms)]);
    if args.json {
        return emit(&serde_json::json!({ "table1": rows, "parallel_efficiency": efficiency }).to_string());
    }
    let heading =
        format!("Table 1 (median of {} runs, ms; the front end's stages in processor time over 8 slices):", args.runs);
    super::output::table1(&heading, &rows, efficiency)
}

fn server(args: &ServerBenchArgs) -> anyhow::Result<()> {
    use marvin::protocol::{Frame, PickSpec, PlaceSpec, WireGrasp, WireObject, WirePose};
    use marvin::server::{CellConfig, Server, ServerConfig};
    let cell =
        CellConfig { world: args.world.clone(), seed: None, cam_from_base: None, expose_truth: false, cameras: None };
    let server = Server::start(ServerConfig::new(cell, "127.0.0.1:0".parse()?))?;
    let mut client =
        marvin::engine::client::Client::connect(&server.addr().to_string(), std::time::Duration::from_secs(5))?;
    let hello = client.hello(None)?;
    for _ in 0..50 {
        client.status()?;
    }
    let mut ms: Vec<f64> = Vec::with_capacity(args.runs as usize);
    for _ in 0..args.runs.max(1) {
        let t = Instant::now();
        client.status()?;
        ms.push(t.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    let quantile = |q: f64| ms[((ms.len() - 1) as f64 * q).round() as usize];
    // Every object planned from its true pose (a benchmark may read the truth), not moved.
    let truth = server.truth()?;
    let base_from_world = truth.world_from_base.to_isometry("world_from_base")?.inverse();
    let library = mesh::Library::load_default()?;
    let in_base = |p: &WirePose| -> anyhow::Result<_> { Ok(base_from_world * p.to_isometry("world_from_model")?) };
    let (mut plan_ms, mut unplanned) = (Vec::new(), 0);
    for o in &truth.objects {
        let base_from_model = in_base(&o.world_from_model)?;
        let grasp = &library.get(&o.model).ok_or_else(|| anyhow::anyhow!("no model {}", o.model))?.grasps[0];
        let obstacles = truth
            .objects
            .iter()
            .filter(|x| x.id != o.id)
            .map(|x| {
                Ok(WireObject {
                    model: x.model.clone(),
                    pose: WirePose::new(Some(Frame::Base), &in_base(&x.world_from_model)?),
                })
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let spec = PickSpec {
            model: o.model.clone(),
            grasp: WireGrasp::new(
                WirePose::new(Some(Frame::Base), &(base_from_model * grasp.model_from_gripper)),
                grasp.opening * 1e3,
            ),
            place: PlaceSpec { bin: hello.bins[0].clone() },
            object: Some(WirePose::new(Some(Frame::Base), &base_from_model)),
            obstacles,
            plan_only: true,
        };
        match client.pick(spec) {
            Ok(reply) => plan_ms.push(reply.plan_ms),
            Err(e) if e.wire().is_some() => unplanned += 1,
            Err(e) => return Err(e.into()),
        }
    }
    plan_ms.sort_by(f64::total_cmp);
    let plan_median = plan_ms.get(plan_ms.len() / 2).copied().unwrap_or(f64::NAN);
    client.bye()?;
    server.stop();
    server.wait()?;
    let doc = serde_json::json!({ "server": {
        "status_p50_ms": quantile(0.5),
        "status_p99_ms": quantile(0.99),
        "pick_plan_ms": plan_median,
        "status_runs": ms.len(),
        "picks_planned": plan_ms.len(),
        "picks_unplanned": unplanned,
    }});
    if args.json {
        return emit(&doc.to_string());
    }
    emit(&format!(
        "status round trip: p50 {:.3} ms, p99 {:.3} ms ({} requests over loopback)",
        quantile(0.5),
        quantile(0.99),
        ms.len()
    ))?;
    emit(&format!(
        "pick planning (IK + paths): median {plan_median:.1} ms over {} objects ({unplanned} could not be planned)",
        plan_ms.len()
    ))
}
