//! A real lens between the scene and the sensor: distortion, blur and vignetting.
//!
//! The rasteriser draws straight lines, so a distorted image is drawn in two steps: the scene
//! is rendered through a *virtual pinhole* (the true camera's intrinsics, widened to take in
//! everything the distorted image shows), then each pixel of the real image takes the radiance
//! of the ideal point its lens maps onto it (`plumb_bob` inverted, bilinear look-up). The blur
//! is then laid on per pixel, by the depth seen there: the thin lens's circle of confusion and
//! the lens's own spread, as Gaussians blended between a few precomputed widths. Vignetting is
//! the `cos^n` law of the ray's angle off the axis.

use crate::realism::CameraAsBuilt;
use mesh::PinholeCamera;
use rayon::prelude::*;

/// Pixels of margin the virtual image keeps round what the real image needs (the bilinear
/// look-up and the blur reach past the edge).
const MARGIN_PX: f64 = 4.0;

/// The virtual pinhole a camera's scene is drawn through: the true camera's focal lengths and
/// pose, with the principal point moved so that every ideal point that the lens maps into the
/// image lies inside.
pub fn virtual_pinhole(cam: &CameraAsBuilt) -> PinholeCamera {
    let p = &cam.pinhole;
    let (w, h) = (p.width as f64, p.height as f64);
    let (mut lo_x, mut lo_y, mut hi_x, mut hi_y) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
    // The border of the image, finely: under barrel distortion the corners reach furthest.
    let steps = 64;
    let border = (0..=steps).flat_map(|i| {
        let t = i as f64 / steps as f64;
        [(t * w - 0.5, -0.5), (t * w - 0.5, h - 0.5), (-0.5, t * h - 0.5), (w - 0.5, t * h - 0.5)]
    });
    for (u, v) in border {
        let (x, y) = ideal_normalised(cam, u, v);
        lo_x = lo_x.min(p.fx * x);
        hi_x = hi_x.max(p.fx * x);
        lo_y = lo_y.min(p.fy * y);
        hi_y = hi_y.max(p.fy * y);
    }
    // The virtual image is the real one grown by whole pixels on each side, so that without
    // distortion every pixel takes its light from one virtual pixel's centre (no resampling blur).
    let (left, top) = ((p.cx + lo_x - MARGIN_PX).floor().min(0.0), (p.cy + lo_y - MARGIN_PX).floor().min(0.0));
    let (right, bottom) =
        ((p.cx + hi_x + MARGIN_PX).ceil().max(w - 1.0), (p.cy + hi_y + MARGIN_PX).ceil().max(h - 1.0));
    PinholeCamera {
        width: (right - left) as u32 + 1,
        height: (bottom - top) as u32 + 1,
        cx: p.cx - left,
        cy: p.cy - top,
        ..p.clone()
    }
}

/// The ideal (undistorted) normalised coordinates of the ray the lens brings to pixel `(u, v)`.
pub fn ideal_normalised(cam: &CameraAsBuilt, u: f64, v: f64) -> (f64, f64) {
    let p = &cam.pinhole;
    let (xd, yd) = ((u - p.cx) / p.fx, (v - p.cy) / p.fy);
    cam.lens.distortion.undistort(xd, yd).unwrap_or((xd, yd))
}

/// Bilinear look-up of a `w`-wide image at `(x, y)`; clamped at the border.
pub fn bilinear(image: &[f32], w: usize, h: usize, x: f64, y: f64) -> f32 {
    let x = x.clamp(0.0, (w - 1) as f64);
    let y = y.clamp(0.0, (h - 1) as f64);
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (ax, ay) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let row = |y: usize| (1.0 - ax) * image[y * w + x0] + ax * image[y * w + x1];
    (1.0 - ay) * row(y0) + ay * row(y1)
}

/// `cos^n` of the angle off the axis of the ray with normalised coordinates `(x, y)`.
pub fn vignetting(x: f64, y: f64, exponent: f64) -> f32 {
    (1.0 + x * x + y * y).powf(-exponent / 2.0) as f32
}

/// Blurs `image` (`w` wide) with a Gaussian whose variance varies per pixel (`variance[i]`,
/// px²), in two passes (along rows, then columns), each pixel weighing its neighbours by its
/// own kernel: the discrete Gaussian of the ladder [`VARIANCE_STEP`] apart nearest its own
/// (within half a step). Where the variance is the same over a kernel's reach this is that
/// Gaussian blur; across a depth step each side keeps its own spread.
pub fn blur_by_variance(image: &[f32], w: usize, variance: &[f32]) -> Vec<f32> {
    let lo = variance.iter().copied().fold(f32::MAX, f32::min).max(0.0);
    let hi = variance.iter().copied().fold(0.0f32, f32::max).max(lo);
    let rungs = ((hi - lo) / VARIANCE_STEP).round() as usize + 1;
    let kernels: Vec<Vec<f32>> = (0..rungs).map(|k| discrete_gaussian(lo + k as f32 * VARIANCE_STEP)).collect();
    let rung: Vec<u16> = variance
        .par_iter()
        .map(|t| (((t - lo) / VARIANCE_STEP).round().max(0.0) as usize).min(rungs - 1) as u16)
        .collect();
    let h = image.len() / w;
    let mut across = vec![0.0f32; image.len()];
    across.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let line = &image[y * w..(y + 1) * w];
        for (x, out) in row.iter_mut().enumerate() {
            *out = tap(&kernels[rung[y * w + x] as usize], x, w, |i| line[i]);
        }
    });
    let mut out = vec![0.0f32; image.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            *o = tap(&kernels[rung[y * w + x] as usize], y, h, |i| across[i * w + x]);
        }
    });
    out
}

/// One pixel of a pass: the neighbours at `centre - r ..= centre + r` along a line of `len`
/// (clamped at its ends), weighed by `kernel`.
#[inline(always)]
fn tap(kernel: &[f32], centre: usize, len: usize, at: impl Fn(usize) -> f32) -> f32 {
    let r = kernel.len() / 2;
    if centre >= r && centre + r < len {
        return kernel.iter().enumerate().map(|(j, k)| k * at(centre + j - r)).sum();
    }
    kernel.iter().enumerate().map(|(j, k)| k * at((centre + j).saturating_sub(r).min(len - 1))).sum()
}

/// Steps in variance (px²) between the kernels of [`blur_by_variance`]: a pixel's variance is
/// within half of this of its own (a sigma of 0.5 px within 0.5%).
pub const VARIANCE_STEP: f32 = 0.01;

/// The discrete Gaussian of variance `t` px² (Lindeberg's `e^-t I_n(t)`, with `I_n` the
/// modified Bessel functions): the kernel whose variance is `t` however small, where a sampled
/// Gaussian of sigma 0.3 px has a variance of 0.008 px², not 0.09. Reaches 3.5 sigma and a pixel more.
pub fn discrete_gaussian(t: f32) -> Vec<f32> {
    if t <= 1e-6 {
        return vec![1.0];
    }
    let t = t as f64;
    let r = (3.5 * t.sqrt()).ceil() as usize + 1;
    // I_n(t) = sum_k (t/2)^(2k+n) / (k! (k+n)!)
    let bessel = |n: usize| {
        let (half, mut term, mut sum) = (t / 2.0, 1.0, 0.0);
        for k in 1..=n {
            term *= half / k as f64;
        }
        for k in 0..60 {
            sum += term;
            term *= half * half / ((k + 1) as f64 * (k + 1 + n) as f64);
            if term < 1e-17 * sum {
                break;
            }
        }
        sum * (-t).exp()
    };
    let side: Vec<f64> = (0..=r).map(bessel).collect();
    let total: f64 = side[0] + 2.0 * side[1..].iter().sum::<f64>();
    (0..=2 * r).map(|i| (side[i.abs_diff(r)] / total) as f32).collect()
}

/// A separable Gaussian blur of sigma `s` pixels, borders clamped.
pub fn gaussian_blur(image: &[f32], w: usize, s: f32) -> Vec<f32> {
    if s <= 1e-3 {
        return image.to_vec();
    }
    let h = image.len() / w;
    let kernel = discrete_gaussian(s * s);
    let r = (kernel.len() / 2) as i64;
    let mut across = vec![0.0f32; image.len()];
    across.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, out) in row.iter_mut().enumerate() {
            *out = kernel
                .iter()
                .enumerate()
                .map(|(k, wt)| wt * image[y * w + (x as i64 + k as i64 - r).clamp(0, w as i64 - 1) as usize])
                .sum();
        }
    });
    let mut out = vec![0.0f32; image.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x, o) in row.iter_mut().enumerate() {
            *o = kernel
                .iter()
                .enumerate()
                .map(|(k, wt)| wt * across[(y as i64 + k as i64 - r).clamp(0, h as i64 - 1) as usize * w + x])
                .sum();
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_uniform_variance_blurs_as_the_plain_gaussian() {
        let w = 40;
        let image: Vec<f32> = (0..w * 30).map(|i| ((i * 7919) % 13) as f32).collect();
        for s in [0.9f32, 1.2] {
            let plain = gaussian_blur(&image, w, s);
            let varying = blur_by_variance(&image, w, &vec![s * s; image.len()]);
            let worst = plain.iter().zip(&varying).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
            assert!(worst < 1e-4, "sigma {s}: differs by {worst}");
        }
    }

    #[test]
    fn a_blurred_step_has_the_asked_spread() {
        let (w, h) = (64, 8);
        let step: Vec<f32> = (0..w * h).map(|i| if i % w >= 32 { 1.0 } else { 0.0 }).collect();
        for s in [0.3f32, 0.8, 1.3] {
            let b = gaussian_blur(&step, w, s);
            // The derivative of a blurred step is the kernel: its variance is s².
            let d: Vec<f32> = (1..w).map(|x| b[4 * w + x] - b[4 * w + x - 1]).collect();
            let mean: f32 = d.iter().enumerate().map(|(i, v)| (i as f32 + 0.5) * v).sum();
            let var: f32 = d.iter().enumerate().map(|(i, v)| (i as f32 + 0.5 - mean).powi(2) * v).sum();
            assert!((var - s * s).abs() < 2e-3, "sigma {s}: variance {var}");
        }
    }

    #[test]
    fn vignetting_follows_the_cosine_law() {
        assert_eq!(vignetting(0.0, 0.0, 4.0), 1.0);
        let angle = 0.3f64;
        let v = vignetting(angle.tan(), 0.0, 4.0);
        assert!((v as f64 - angle.cos().powi(4)).abs() < 1e-6);
    }
}
