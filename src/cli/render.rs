//! `marvin render`: settle a world, render the stereo pair, write images, maps and scene.json.

use anyhow::Context;
use image::{ImageBuffer, Luma};
use sim::Scenario;
use sim::record::{DEPTH_UNIT_M, SceneRecord};
use sim::render::Frame;
use std::path::Path;
use std::time::Instant;

pub fn run(world: &Path, seed: Option<u64>, out: &Path) -> anyhow::Result<()> {
    let scn = Scenario::load(world)?;
    let seed = seed.unwrap_or(scn.world.seed);
    let t0 = Instant::now();
    let (scene, _) = super::output::settle(&scn, seed);
    eprintln!(
        "settled {} objects in {:.1} s simulated ({:.2} s wall)",
        scene.objects.len(),
        scene.settle.simulated_s,
        t0.elapsed().as_secs_f64(),
    );
    let imaging = sim::imaging::Imaging::new(&scn.world);
    let t1 = Instant::now();
    let (left, right) = imaging.render_stereo(&scene.render_scene(&scn.library, &imaging), seed);
    eprintln!("rendered the stereo pair ({:?} preset) in {:.1} ms", imaging.preset, t1.elapsed().as_secs_f64() * 1e3);
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    for (name, frame) in [("left", &left), ("right", &right)] {
        write_frame(frame, name, out)?;
    }
    let record = SceneRecord::new(&scn, &scene, &imaging);
    let path = out.join("scene.json");
    std::fs::write(&path, serde_json::to_string_pretty(&record)?)
        .with_context(|| format!("writing {}", path.display()))?;
    eprintln!("wrote {}", out.display());
    Ok(())
}

fn write_frame(f: &Frame, name: &str, out: &Path) -> anyhow::Result<()> {
    let (w, h) = (f.width as u32, f.height as u32);
    let save = |file: String, result: image::ImageResult<()>| {
        result.with_context(|| format!("writing {}", out.join(file).display()))
    };
    let grey = ImageBuffer::<Luma<u8>, _>::from_raw(w, h, f.image.clone()).context("image size")?;
    save(format!("{name}.png"), grey.save(out.join(format!("{name}.png"))))?;
    let depth: Vec<u16> =
        f.depth.iter().map(|&d| (d as f64 / DEPTH_UNIT_M).round().min(u16::MAX as f64) as u16).collect();
    let depth = ImageBuffer::<Luma<u16>, _>::from_raw(w, h, depth).context("depth size")?;
    save(format!("depth_{name}.png"), depth.save(out.join(format!("depth_{name}.png"))))?;
    let ids = ImageBuffer::<Luma<u16>, _>::from_raw(w, h, f.ids.clone()).context("id map size")?;
    save(format!("ids_{name}.png"), ids.save(out.join(format!("ids_{name}.png"))))?;
    Ok(())
}
