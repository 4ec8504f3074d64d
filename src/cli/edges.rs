//! `marvin edges`: Canny and edge strings on any grey image.

use super::output::emit;
use anyhow::Context;
use image::{Rgb, RgbImage};
use serde::Serialize;
use std::path::Path;
use vision::{CannyParams, EdgeString, Edgel, GreyImage, canny, link_strings};

/// Strings shorter than this many edgels are dropped.
pub const MIN_STRING: usize = 5;

/// Reads any image file as 8-bit grey, naming the file in every error.
/// Smallest and largest Gaussian widths Canny takes, pixels: below 0.3 the kernel is a single
/// tap (no smoothing, every pixel of noise an edge); above 10 it spans more than 60 pixels.
pub const SIGMA_RANGE: (f32, f32) = (0.3, 10.0);

/// `--sigma`: a finite width within [`SIGMA_RANGE`].
pub fn parse_sigma(s: &str) -> Result<f32, String> {
    let v: f32 = s.trim().parse().map_err(|e| format!("`{s}` is not a number: {e}"))?;
    let (lo, hi) = SIGMA_RANGE;
    if v.is_finite() && (lo..=hi).contains(&v) { Ok(v) } else { Err(format!("{v} is outside {lo}..={hi} pixels")) }
}

pub fn load_grey(path: &Path) -> anyhow::Result<GreyImage> {
    load_grey_noting(path, &mut Vec::new())
}

/// As [`load_grey`]; a colour image is read as its luma, and `notes` is told so.
pub fn load_grey_noting(path: &Path, notes: &mut Vec<String>) -> anyhow::Result<GreyImage> {
    let img = image::open(path).with_context(|| format!("{}: cannot read as an image", path.display()))?;
    if img.color().has_color() {
        notes.push(format!("{}: a colour image ({:?}), read as grey (its luma)", path.display(), img.color()));
    }
    let grey = img.into_luma8();
    let (w, h) = (grey.width() as usize, grey.height() as usize);
    GreyImage::new(w, h, grey.into_raw())
        .with_context(|| format!("{}: pixel count does not match size", path.display()))
}

#[derive(Serialize)]
struct EdgesJson<'a> {
    width: usize,
    height: usize,
    params: CannyParams,
    edgels: &'a [Edgel],
    /// Each string as indices into `edgels`, in order along the string.
    strings: Vec<&'a [u32]>,
}

pub fn run(image: &Path, sigma: f32, json: bool, out: Option<&Path>) -> anyhow::Result<()> {
    let img = load_grey(image)?;
    let params = CannyParams { sigma, ..CannyParams::default() };
    let map = canny(&img, &params);
    let strings = link_strings(&map, MIN_STRING);
    if json {
        let doc = EdgesJson {
            width: img.width,
            height: img.height,
            params,
            edgels: &map.edgels,
            strings: strings.iter().map(|s| s.edgels.as_slice()).collect(),
        };
        emit(&serde_json::to_string(&doc)?)?;
    } else {
        let in_strings: usize = strings.iter().map(|s| s.edgels.len()).sum();
        emit(&format!(
            "{}: {} edgels, {} strings of >= {MIN_STRING} edgels holding {in_strings}",
            image.display(),
            map.edgels.len(),
            strings.len()
        ))?;
    }
    if let Some(path) = out {
        draw(&img, &strings, &map.edgels).save(path).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// The image dimmed, each string's edgels in a colour of its own.
pub fn draw(img: &GreyImage, strings: &[EdgeString], edgels: &[Edgel]) -> RgbImage {
    let mut out = RgbImage::from_fn(img.width as u32, img.height as u32, |x, y| {
        let g = img.at(x as usize, y as usize) / 3;
        Rgb([g, g, g])
    });
    for (k, s) in strings.iter().enumerate() {
        let colour = palette(k);
        for &i in &s.edgels {
            let e = &edgels[i as usize];
            let (x, y) = (e.x.round() as u32, e.y.round() as u32);
            if x < out.width() && y < out.height() {
                out.put_pixel(x, y, colour);
            }
        }
    }
    out
}

fn palette(k: usize) -> Rgb<u8> {
    const COLOURS: [[u8; 3]; 6] =
        [[255, 80, 80], [80, 255, 80], [90, 140, 255], [255, 230, 60], [255, 90, 255], [60, 240, 240]];
    Rgb(COLOURS[k % COLOURS.len()])
}
