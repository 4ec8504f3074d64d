//! `marvin bench`: medians of repeated runs. Never a pass/fail test: the machines are shared.

use clap::Subcommand;
use sim::render::{Light, RenderScene, render_stereo};
use sim::{Scenario, Scene};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Subcommand)]
pub enum BenchTarget {
    /// Median time to render the stereo pair of the default scene.
    Render {
        #[arg(long, default_value = "worlds/widgets.toml")]
        world: PathBuf,
        /// Timed repetitions.
        #[arg(long, default_value_t = 50)]
        runs: usize,
        /// Print `{"render": {"median_ms": X}}`.
        #[arg(long)]
        json: bool,
    },
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

pub fn run(target: BenchTarget) -> anyhow::Result<()> {
    match target {
        BenchTarget::Render { world, runs, json } => {
            let scn = Scenario::load(&world)?;
            let scene = Scene::settle(&scn, scn.world.seed);
            let calib = sim::rig::calibration(&scn.world.cameras);
            let light = Light::from(&scn.world.light);
            let sigma = scn.world.render.noise_sigma;
            // Timed: shading the settled scene and rendering both cameras (images, depth, ids).
            let median = median_ms(runs, || {
                let rs = RenderScene::new(scene.world_meshes(&scn.library), &light);
                std::hint::black_box(render_stereo(&rs, &calib, sigma, scn.world.seed));
            });
            if json {
                println!(
                    "{}",
                    serde_json::json!({ "render": { "median_ms": median } })
                );
            } else {
                println!(
                    "render: stereo pair of {} in {median:.2} ms (median of {runs}, {} threads)",
                    world.display(),
                    rayon::current_num_threads()
                );
            }
            Ok(())
        }
    }
}
