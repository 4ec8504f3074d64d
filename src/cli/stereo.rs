//! `marvin stereo`: the vision front end on any image pair, rendered or real.

use super::edges::load_grey;
use super::output::emit;
use anyhow::{Context, bail};
use image::{Rgb, RgbImage};
use marvin::front_end::{FrontEnd, Geometry, Workspace, run_with};
use serde::Serialize;
use std::path::Path;
use vision::{CannyParams, GreyImage};

/// Largest disparity, either way, that `--disparity` takes: the widest image a camera may have.
const MAX_DISPARITY_PX: f32 = 8192.0;

/// Parses `MIN:MAX`.
pub fn parse_range(s: &str) -> Result<(f32, f32), String> {
    let (a, b) = s.split_once(':').ok_or_else(|| format!("`{s}` is not MIN:MAX"))?;
    let parse = |v: &str| v.trim().parse::<f32>().map_err(|e| format!("`{v}` in `{s}`: {e}"));
    let (lo, hi) = (parse(a)?, parse(b)?);
    let limit = MAX_DISPARITY_PX;
    if !(lo.is_finite() && hi.is_finite() && lo.abs() <= limit && hi.abs() <= limit) {
        return Err(format!("`{s}`: disparities must be finite and within -{limit}..={limit} pixels"));
    }
    if lo < hi { Ok((lo, hi)) } else { Err(format!("`{s}`: MIN must be below MAX")) }
}

pub fn geometry(
    calib: Option<&Path>,
    cameras: Option<&Path>,
    rectified: bool,
    disparity: Option<(f32, f32)>,
) -> anyhow::Result<Geometry> {
    match (calib, cameras, rectified, disparity) {
        (Some(path), None, false, None) => {
            let calib = mesh::StereoCalibration::load(path)?;
            Ok(Geometry::Calibrated(Box::new(calib)))
        }
        (None, Some(path), false, None) => {
            let file = camera_calib::file::CamerasFile::load(path)?;
            Ok(Geometry::Calibrated(Box::new(file.stereo_calibration())))
        }
        (None, None, true, Some((disparity_min, disparity_max))) => {
            Ok(Geometry::Rectified { disparity_min, disparity_max })
        }
        _ => bail!("give one of --calib FILE or --cameras FILE, or --rectified with --disparity MIN:MAX"),
    }
}

#[derive(Serialize)]
struct MatchJson {
    /// Left edgel position in the left image (unrectified pixels).
    x: f32,
    y: f32,
    /// `x_left - x_right` in rectified pixels.
    disparity: f32,
}

pub fn run(
    left: &Path,
    right: &Path,
    geometry: &Geometry,
    slices: usize,
    json: bool,
    out: Option<&Path>,
) -> anyhow::Result<()> {
    let (l, r) = (load_grey(left)?, load_grey(right)?);
    if (l.width, l.height) != (r.width, r.height) {
        bail!(
            "{} is {}x{} but {} is {}x{}: a stereo pair must match",
            left.display(),
            l.width,
            l.height,
            right.display(),
            r.width,
            r.height
        );
    }
    if let Geometry::Calibrated(c) = geometry
        && (c.left.width as usize, c.left.height as usize) != (l.width, l.height)
    {
        bail!("the calibration is for {}x{} images, these are {}x{}", c.left.width, c.left.height, l.width, l.height);
    }
    let fe = match geometry {
        Geometry::Calibrated(calib) if slices > 1 => {
            vision::front_end::slices::run_sliced(&l, &r, calib, &Workspace::default(), &CannyParams::default(), slices)
        }
        _ => run_with(&l, &r, geometry, &Workspace::default(), &CannyParams::default()),
    };
    if json {
        let matches: Vec<MatchJson> = fe
            .matches
            .iter()
            .map(|m| {
                let e = &fe.left.edgels[m.left as usize];
                MatchJson { x: e.x, y: e.y, disparity: m.disparity }
            })
            .collect();
        let timings: serde_json::Map<String, serde_json::Value> =
            fe.timings_ms.iter().map(|(k, v)| (k.to_string(), serde_json::json!(v))).collect();
        let lines2d: Vec<_> = fe.lines2d.iter().map(|l| fe.line2d_in_image(l)).collect();
        let lines3d: Vec<_> = fe
            .lines3d
            .iter()
            .map(|l| serde_json::json!({ "a": l.a, "b": l.b, "sigma_a": l.sigma_a, "sigma_b": l.sigma_b }))
            .collect();
        let doc = serde_json::json!({
            "matches": matches,
            "lines2d": lines2d,
            "lines3d": lines3d,
            "timings_ms": timings,
        });
        emit(&doc.to_string())?;
    } else {
        emit(&format!(
            "{} left and {} right edgels, {} matches, {} 2D lines, {} 3D lines ({})",
            fe.left.edgels.len(),
            fe.right.edgels.len(),
            fe.matches.len(),
            fe.lines2d.len(),
            fe.lines3d.len(),
            fe.timings_ms.iter().map(|(k, v)| format!("{k} {v:.1} ms")).collect::<Vec<_>>().join(", ")
        ))?;
    }
    if let Some(dir) = out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let path = dir.join("matches.png");
        draw_matches(&l, &fe).save(&path).with_context(|| format!("writing {}", path.display()))?;
        let path = dir.join("edges.png");
        super::edges::draw(&l, &fe.left_strings, &fe.left.edgels)
            .save(&path)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// The left image dimmed, each matched edgel coloured by disparity (blue far .. red near),
/// unmatched edgels grey.
fn draw_matches(img: &GreyImage, fe: &FrontEnd) -> RgbImage {
    let mut out = RgbImage::from_fn(img.width as u32, img.height as u32, |x, y| {
        let g = img.at(x as usize, y as usize) / 3;
        Rgb([g, g, g])
    });
    let put = |out: &mut RgbImage, x: f32, y: f32, c: Rgb<u8>| {
        let (x, y) = (x.round() as u32, y.round() as u32);
        if x < out.width() && y < out.height() {
            out.put_pixel(x, y, c);
        }
    };
    for e in &fe.left.edgels {
        put(&mut out, e.x, e.y, Rgb([110, 110, 110]));
    }
    let (lo, hi) = fe.matches.iter().fold((f32::MAX, f32::MIN), |(a, b), m| (a.min(m.disparity), b.max(m.disparity)));
    for m in &fe.matches {
        let t = ((m.disparity - lo) / (hi - lo).max(1e-3)).clamp(0.0, 1.0);
        let e = &fe.left.edgels[m.left as usize];
        put(
            &mut out,
            e.x,
            e.y,
            Rgb([(255.0 * t) as u8, (255.0 * (1.0 - (2.0 * t - 1.0).abs())) as u8, (255.0 * (1.0 - t)) as u8]),
        );
    }
    out
}
