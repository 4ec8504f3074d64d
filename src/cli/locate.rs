//! `marvin locate`: render a scene, run the front end and the matcher, and say how each report
//! compares with the truth.

use super::output::emit;
use super::scene::{matcher_models, run_pipeline};
use anyhow::{Context, bail};
use image::{Rgb, RgbImage};
use marvin::engine::perception::part_params;
use marvin::eval::{CORRECT_POS_M, CORRECT_ROT_DEG, pose_error, symmetries, visible_fraction};
use nalgebra::Isometry3;
use sim::Scenario;
use std::path::{Path, PathBuf};
use vision::matcher::{MatchParams, Seg, locate_all};

/// The command's arguments.
pub struct LocateArgs {
    pub world: PathBuf,
    pub seed: Option<u64>,
    /// Only these models (default: every library model but the tools).
    pub models: Option<Vec<String>>,
    pub json: bool,
    /// Folder for located.png.
    pub out: Option<PathBuf>,
    /// Where to record the scene for rerun, if anywhere.
    pub rerun: Option<PathBuf>,
    /// A camera calibration file (`marvin calibrate cameras`) vision sees through.
    pub cameras: Option<PathBuf>,
    /// A hand-eye calibration file that places the table (else one is made first).
    pub hand_eye: Option<PathBuf>,
}

pub fn run(args: LocateArgs, canny: &vision::CannyParams) -> anyhow::Result<()> {
    let LocateArgs { world, seed, models, json, out, rerun, cameras, hand_eye } = args;
    let (world, out, rerun) = (world.as_path(), out.as_deref(), rerun.as_deref());
    let scn = Scenario::load(world)?;
    if let Some(names) = &models {
        for n in names {
            if scn.library.get(n).is_none() {
                bail!(
                    "--models: no model `{n}` in the library (it has: {})",
                    scn.library.names().collect::<Vec<_>>().join(", ")
                );
            }
        }
    }
    let seed = seed.unwrap_or(scn.world.seed);
    let imaging = sim::imaging::Imaging::new(&scn.world);
    let cams = super::scene::eval_cameras(&imaging, cameras.as_deref())?;
    let calib = cams.vision.clone();
    let table = super::table::cam_from_table(world, &scn, &calib, hand_eye.as_deref(), seed, json)?;
    let p = run_pipeline(&scn, &imaging, seed, canny, &cams, table.cam_from_table.as_ref());
    let lines: Vec<Seg> = p.front_end.lines3d.iter().map(|l| Seg::new(l.start(), l.end())).collect();
    let sought = matcher_models(&scn.library, models.as_deref());
    let evidence = vision::matcher::verify::ImageEvidence::of_pair(&calib, &p.front_end);
    let located = locate_all(&sought, &lines, &part_params(table.cam_from_table.as_ref()), Some(&evidence));
    // Compare with the truth (evaluation only).
    let truths: Vec<(String, Isometry3<f64>)> =
        p.scene.objects.iter().map(|o| (o.model.clone(), calib.left.cam_from_world() * o.world_from_model)).collect();
    let mut taken = vec![false; truths.len()];
    let mut rows = Vec::new();
    for loc in &located {
        let sym = symmetries(&scn.library.models[&loc.model]);
        let best = truths
            .iter()
            .enumerate()
            .filter(|(i, (m, _))| *m == loc.model && !taken[*i])
            .map(|(i, (_, t))| (i, pose_error(&loc.cam_from_model, t, &sym)))
            .min_by(|a, b| a.1.0.total_cmp(&b.1.0));
        let correct = best.is_some_and(|(_, (pos, rot))| pos <= CORRECT_POS_M && rot.to_degrees() <= CORRECT_ROT_DEG);
        if let (true, Some((i, _))) = (correct, best) {
            taken[i] = true;
        }
        let grasp = loc.grasps.first().map(|(cam_from_gripper, _)| *cam_from_gripper);
        rows.push(serde_json::json!({
            "model": loc.model,
            // The true object it was matched to (scene.json's id), if it was right.
            "object": best.filter(|_| correct).map(|(i, _)| p.scene.objects[i].id),
            "cam_from_model": mesh::pose::PoseRecord::from(&loc.cam_from_model),
            "grasp_cam_from_gripper": grasp.as_ref().map(mesh::pose::PoseRecord::from),
            "support_fraction": loc.support_fraction,
            "image_support": loc.image_support,
            // The front end's 3D lines the pose rests on (`cam` frame, metres).
            "scene_lines": loc.scene_lines.iter().map(|&j| serde_json::json!({
                "index": j,
                "a_m": [lines[j].a.x, lines[j].a.y, lines[j].a.z],
                "b_m": [lines[j].b.x, lines[j].b.y, lines[j].b.z],
            })).collect::<Vec<_>>(),
            "correct": correct,
            "pos_err_mm": best.map(|(_, (pos, _))| pos * 1e3),
            "rot_err_deg": best.map(|(_, (_, rot))| rot.to_degrees()),
        }));
    }
    let sought_names: Vec<&str> = sought.iter().map(|m| m.name.as_str()).collect();
    // Each object missed, with what the matcher could have found at its true pose.
    let mp = MatchParams::default();
    let missed_truths: Vec<usize> =
        (0..truths.len()).filter(|&i| !taken[i] && sought_names.contains(&truths[i].0.as_str())).collect();
    let missed: Vec<serde_json::Value> = missed_truths
        .iter()
        .map(|&i| (i, &truths[i]))
        .filter_map(|(i, (name, pose))| {
            let model = sought.iter().find(|m| &m.name == name)?;
            let (support, lines_seen) = vision::matcher::support_at(model, pose, &lines, &mp);
            Some(serde_json::json!({
                "model": name,
                // The id of scene.json and `marvin pick --object`.
                "object": p.scene.objects[i].id,
                "visible_fraction": visible_fraction(
                    &scn.library.models[name],
                    &(p.cams.true_left.pinhole.cam_from_world() * p.scene.objects[i].world_from_model),
                    &p.cams.true_left,
                    &p.left.depth
                ),
                "support_fraction_at_truth": support,
                "supported_lines_at_truth": lines_seen,
                "image_support_at_truth": vision::matcher::verify::image_support(model, pose, &evidence),
            }))
        })
        .collect();
    if json {
        emit(
            &serde_json::json!({ "seed": seed, "table": table.source, "located": rows, "missed": missed }).to_string(),
        )?;
    } else {
        for r in &rows {
            emit(&format!(
                "{:10} support {:.2}  {}",
                r["model"].as_str().unwrap_or("?"),
                r["support_fraction"].as_f64().unwrap_or(0.0),
                if r["correct"].as_bool() == Some(true) {
                    format!(
                        "ok: {:.2} mm, {:.2} deg",
                        r["pos_err_mm"].as_f64().unwrap_or(f64::NAN),
                        r["rot_err_deg"].as_f64().unwrap_or(f64::NAN)
                    )
                } else if let (Some(pos), Some(rot)) = (r["pos_err_mm"].as_f64(), r["rot_err_deg"].as_f64()) {
                    format!(
                        "FALSE: the nearest {} is {pos:.1} mm, {rot:.1} deg away",
                        r["model"].as_str().unwrap_or("?")
                    )
                } else {
                    "FALSE: no such object there".to_string()
                }
            ))?;
        }
        let names: Vec<&str> = missed.iter().filter_map(|m| m["model"].as_str()).collect();
        emit(&format!("missed: {}", if names.is_empty() { "none".to_string() } else { names.join(", ") }))?;
        for m in &missed {
            emit(&format!(
                "  {} (object {}): {:.0}% of its edges visible; at its true pose 3D support {:.2} on {} lines, image {:.2}",
                m["model"].as_str().unwrap_or("?"),
                m["object"],
                m["visible_fraction"].as_f64().unwrap_or(0.0) * 100.0,
                m["support_fraction_at_truth"].as_f64().unwrap_or(0.0),
                m["supported_lines_at_truth"],
                m["image_support_at_truth"].as_f64().unwrap_or(0.0),
            ))?;
        }
    }
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let path = dir.join("located.png");
        let judged: Vec<_> = located.iter().zip(&rows).map(|(l, r)| (l, r["correct"] == true)).collect();
        let missed_poses: Vec<(&str, Isometry3<f64>)> =
            missed_truths.iter().map(|&i| (truths[i].0.as_str(), truths[i].1)).collect();
        draw(&p.left, &judged, &missed_poses, &scn, &calib.left)
            .save(&path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(path) = rerun {
        record(path, &scn, &p, &calib, &located)?;
        if !json {
            eprintln!("recorded the scene in {} (open it with `rerun {}`)", path.display(), path.display());
        }
    }
    Ok(())
}

/// The scene recorded for rerun, in the robot's base frame as a run's recording is (the world's
/// when the world has no robot): both cameras with their images, the edgels, 2D and 3D lines,
/// the located parts, the table and bins.
fn record(
    path: &Path,
    scn: &Scenario,
    p: &super::scene::Pipeline,
    calib: &mesh::StereoCalibration,
    located: &[vision::matcher::Located],
) -> anyhow::Result<()> {
    let png = |f: &sim::render::Frame| -> anyhow::Result<Vec<u8>> {
        let img = image::GrayImage::from_raw(f.width as u32, f.height as u32, f.image.clone()).context("image size")?;
        let mut bytes = std::io::Cursor::new(Vec::new());
        img.write_to(&mut bytes, image::ImageFormat::Png)?;
        Ok(bytes.into_inner())
    };
    let grey =
        |f: &sim::render::Frame| vision::GreyImage::new(f.width, f.height, f.image.clone()).context("image size");
    // The pair as the vision pipeline holds it: the right camera in the left's frame.
    let mut rig = calib.clone();
    rig.left.world_from_cam = Isometry3::identity();
    rig.right.world_from_cam = calib.left.cam_from_world() * calib.right.world_from_cam;
    let pair = marvin::engine::perception::Pair { left: grey(&p.left)?, right: grey(&p.right)?, calib: rig };
    let base_from_world = scn.world.robot.as_ref().map_or(Isometry3::identity(), |r| r.world_from_base().inverse());
    let mut r =
        marvin::engine::recording::Recording::start(&marvin::engine::recording::Sink::File(path.to_path_buf()))?;
    r.at(0, 0.0);
    r.frame(&(base_from_world * calib.left.world_from_cam));
    r.stereo([png(&p.left)?, png(&p.right)?], &pair, &p.front_end)?;
    r.located(located, &[], &scn.library)?;
    r.cell_layout(scn)?;
    r.text(&format!("seed {}: {} parts located", p.scene.seed, located.len()))?;
    r.finish()
}

/// The left image with each located model's wireframe drawn where the matcher put it (a colour
/// each; false reports red) and each missed object's true wireframe dashed in white.
fn draw(
    frame: &sim::render::Frame,
    located: &[(&vision::matcher::Located, bool)],
    missed: &[(&str, Isometry3<f64>)],
    scn: &Scenario,
    cam: &mesh::PinholeCamera,
) -> RgbImage {
    let mut img = RgbImage::from_fn(frame.width as u32, frame.height as u32, |x, y| {
        let g = frame.image[y as usize * frame.width + x as usize];
        Rgb([g, g, g])
    });
    const COLOURS: [[u8; 3]; 5] = [[60, 255, 60], [80, 140, 255], [255, 220, 40], [255, 80, 255], [40, 230, 230]];
    const FALSE_REPORT: [u8; 3] = [255, 40, 40];
    for (k, (loc, correct)) in located.iter().enumerate() {
        let colour = if *correct { COLOURS[k % COLOURS.len()] } else { FALSE_REPORT };
        draw_wireframe(&mut img, &scn.library.models[&loc.model], &loc.cam_from_model, cam, Rgb(colour), false);
    }
    for (model, pose) in missed {
        draw_wireframe(&mut img, &scn.library.models[*model], pose, cam, Rgb([255, 255, 255]), true);
    }
    img
}

/// Draws `model`'s wireframe at `cam_from_model` into `img`, solid or dashed.
fn draw_wireframe(
    img: &mut RgbImage,
    model: &mesh::Model,
    cam_from_model: &Isometry3<f64>,
    cam: &mesh::PinholeCamera,
    colour: Rgb<u8>,
    dashed: bool,
) {
    for s in &model.wireframe {
        let (Some(a), Some(b)) = (cam.project_cam(&(cam_from_model * s.a)), cam.project_cam(&(cam_from_model * s.b)))
        else {
            continue;
        };
        let steps = (b - a).norm().ceil().max(1.0) as usize;
        for i in (0..=steps).filter(|i| !dashed || i % 8 < 4) {
            let q = a + (b - a) * (i as f64 / steps as f64);
            let (x, y) = (q.x.round(), q.y.round());
            if x >= 0.0 && y >= 0.0 && (x as u32) < img.width() && (y as u32) < img.height() {
                img.put_pixel(x as u32, y as u32, colour);
            }
        }
    }
}
