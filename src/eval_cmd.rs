//! `marvin eval`: seeded scenes run through the pipeline and compared with ground truth.

use clap::Subcommand;
use marvin::eval::{DisparityStats, LineStats, disparity_stats, line_stats};
use marvin::truth::TruthScene;
use sim::render::{Light, RenderScene, render_stereo};
use sim::{Scenario, Scene};
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Subcommand)]
pub enum EvalTarget {
    /// The vision front end: render, run, compare with ground truth.
    ///
    /// JSON keys so far: `disparity_within_0_5px` and `wrong_matches` (fractions of matched
    /// edgels whose disparity is within 0.5 px of the true one / more than 2 px off; at an
    /// occluding boundary the true disparity is the nearer surface's), `matches_per_scene`,
    /// `endpoint_err_mm_median` and `_p90` (3D line ends from the nearest true feature edge),
    /// `coverage` (of visible feature-edge length in pieces >= 20 px long in the image, the part
    /// a 3D line runs along within 3 mm and 10 deg), `timings_ms` (median per stage: with slices,
    /// each stage's processor time summed over the slices, then `slices` and `join` wall time).
    Vision {
        world: PathBuf,
        #[arg(long, default_value_t = 20)]
        scenes: u64,
        /// First seed; scene k uses seed + k.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Slices of the front end (1: whole images).
        #[arg(long, default_value_t = 8)]
        slices: usize,
        #[arg(long)]
        json: bool,
    },
}

pub fn run(target: EvalTarget) -> anyhow::Result<()> {
    let EvalTarget::Vision { world, scenes, seed, slices, json } = target;
    let scn = Scenario::load(&world)?;
    let calib = sim::rig::calibration(&scn.world.cameras);
    let light = Light::from(&scn.world.light);
    let mut total = DisparityStats::default();
    let mut lines = LineStats::default();
    let mut timings: BTreeMap<&'static str, Vec<f64>> = BTreeMap::new();
    for k in 0..scenes {
        let s = seed + k;
        let scene = Scene::settle(&scn, s);
        let (l, r) = render_stereo(
            &RenderScene::new(scene.world_meshes(&scn.library), &light),
            &calib,
            scn.world.render.noise_sigma,
            s,
        );
        let left = vision::GreyImage::new(l.width, l.height, l.image).expect("a rendered frame is whole");
        let right = vision::GreyImage::new(r.width, r.height, r.image).expect("a rendered frame is whole");
        let params = vision::CannyParams::default();
        let fe = if slices > 1 {
            vision::slices::run_sliced(&left, &right, &calib, &params, slices)
        } else {
            marvin::front_end::run(&left, &right, &calib, &params)
        };
        let truth = TruthScene::new(scene.world_meshes(&scn.library).map(|(_, m)| m));
        let stats = disparity_stats(&fe, &truth, &calib);
        let line = line_stats(&fe, &scene, &scn.library, &calib, &l.depth);
        eprintln!(
            "scene {}/{scenes} (seed {s}): {} matches, {:.3} within 0.5 px, {:.3} wrong; {} 3D lines, ends {:.2} mm median, coverage {:.2}",
            k + 1,
            stats.evaluated,
            stats.within_fraction(),
            stats.wrong_fraction(),
            line.endpoint_err_mm.len() / 2,
            line.endpoint_quantile(0.5),
            line.coverage()
        );
        total.add(&stats);
        lines.add(&line);
        for (name, ms) in fe.timings_ms {
            timings.entry(name).or_default().push(ms);
        }
    }
    let medians: BTreeMap<&str, f64> = timings
        .into_iter()
        .map(|(k, mut v)| {
            v.sort_by(f64::total_cmp);
            (k, v[v.len() / 2])
        })
        .collect();
    let report = serde_json::json!({
        "scenes": scenes,
        "disparity_within_0_5px": total.within_fraction(),
        "wrong_matches": total.wrong_fraction(),
        "matches_per_scene": total.evaluated as f64 / scenes.max(1) as f64,
        "endpoint_err_mm_median": lines.endpoint_quantile(0.5),
        "endpoint_err_mm_p90": lines.endpoint_quantile(0.9),
        "coverage": lines.coverage(),
        "lines3d_per_scene": lines.endpoint_err_mm.len() as f64 / 2.0 / scenes.max(1) as f64,
        "timings_ms": medians,
    });
    if json { crate::emit(&report.to_string()) } else { crate::emit(&serde_json::to_string_pretty(&report)?) }
}
