//! `marvin render`: settle a world, render the stereo pair, write images, maps, scene.json and
//! scene.obj; with `--scenes`, a folder of such scenes, one a seed.

use anyhow::Context;
use image::{ImageBuffer, Luma};
use sim::Scenario;
use sim::record::{DEPTH_UNIT_M, SceneRecord};
use sim::render::Frame;
use std::path::Path;
use std::time::Instant;

/// One scene into `out`, or `scenes` of them from `seed` on, each into `out/<seed>`.
pub fn run(world: &Path, seed: Option<u64>, out: &Path, scenes: Option<u64>) -> anyhow::Result<()> {
    let scn = Scenario::load(world)?;
    let seed = seed.unwrap_or(scn.world.seed);
    match scenes {
        None => render_one(&scn, seed, out),
        Some(n) => (seed..seed + n).try_for_each(|s| render_one(&scn, s, &out.join(s.to_string()))),
    }
}

fn render_one(scn: &Scenario, seed: u64, out: &Path) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let (scene, _) = super::output::settle(scn, seed);
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
    write_obj(&scene, &scn.library, &out.join("scene.obj"))?;
    let record = SceneRecord::new(scn, &scene, &imaging);
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

/// The settled scene's surfaces as a Wavefront OBJ in the world frame (metres, z up): one object
/// a surface, named as the id maps number them (`object_<id>_<model>`, `arm_<id>_<link>`) or by
/// its static box's name, spaces as underscores (`table`, `bin_a_wall_-x`), so that another renderer can image the
/// same scene.
fn write_obj(scene: &sim::Scene, library: &mesh::Library, path: &Path) -> anyhow::Result<()> {
    use std::fmt::Write;
    let statics = scene.statics.iter().map(|b| (b.name.replace(' ', "_"), b.mesh()));
    let objects = scene.objects.iter().map(|o| {
        (format!("object_{}_{}", o.id, o.model), library.models[&o.model].mesh.transformed(&o.world_from_model))
    });
    let arm = scene
        .arm
        .iter()
        .enumerate()
        .map(|(k, (link, m))| (format!("arm_{}_{link}", sim::render::arm_link_id(k)), m.clone()));
    let mut text = String::from("# marvin render: the settled scene, world frame, metres\n");
    let mut first = 1;
    for (name, m) in statics.chain(objects).chain(arm) {
        writeln!(text, "o {name}")?;
        for v in &m.vertices {
            writeln!(text, "v {:.6} {:.6} {:.6}", v.x, v.y, v.z)?;
        }
        for t in &m.triangles {
            writeln!(text, "f {} {} {}", first + t[0] as usize, first + t[1] as usize, first + t[2] as usize)?;
        }
        first += m.vertices.len();
    }
    std::fs::write(path, text).with_context(|| format!("writing {}", path.display()))
}
