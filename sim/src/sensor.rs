//! A CCD sensor: light to electrons to grey levels.
//!
//! Each pixel collects `e = E v w (1 + g) + o` electrons from the irradiance `E` the lens
//! brings it (in the renderer's brightness units), with `v` the vignetting, `w` the electrons a
//! white surface under irradiance 1 gives, `g` the pixel's fixed gain error (PRNU) and `o` its
//! fixed offset (DSNU). Shot noise (Poisson, drawn as a Gaussian of variance `e`, which it is
//! to well under a grey level at these counts) and read noise are added, the signal saturates
//! at the full well, passes the response curve `signal^gamma`, is scaled by the camera's gain,
//! lifted by its black level and quantised to 8 bits.
//!
//! The fixed patterns are drawn from the camera's own seed (the same sensor in every capture);
//! the temporal noise from the capture's seed, row by row, so images do not depend on thread
//! scheduling.

use crate::realism::Sensor;
use rand::{SeedableRng, rngs::Xoshiro256PlusPlus};
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

/// What one sensor keeps from frame to frame: its fixed patterns (per-pixel gain factor and
/// offset in electrons) and its response curve, tabulated.
#[derive(Debug, Clone)]
pub struct FixedPattern {
    gain: Vec<f32>,
    offset_e: Vec<f32>,
    /// The sensor's response tabulated (see [`RESPONSE_STEPS`]).
    response: Vec<f64>,
}

impl FixedPattern {
    pub fn new(sensor: &Sensor, pixels: usize, seed: u64) -> FixedPattern {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0xD1B5_4A32_D192_ED03);
        let mut gain = Vec::with_capacity(pixels);
        let mut offset_e = Vec::with_capacity(pixels);
        for _ in 0..pixels {
            let (g, o): (f32, f32) = (StandardNormal.sample(&mut rng), StandardNormal.sample(&mut rng));
            gain.push(1.0 + sensor.prnu as f32 * g);
            // A dark current's offset is never negative on average; its spread is.
            offset_e.push((sensor.dsnu_e as f32 * (1.0 + o)).max(0.0));
        }
        let response = (0..=RESPONSE_STEPS)
            .map(|k| sensor.grey_level(k as f64 / RESPONSE_STEPS as f64 * sensor.full_well_e))
            .collect();
        FixedPattern { gain, offset_e, response }
    }
}

/// Mean electrons of pixel `i` under `irradiance` (vignetting included).
pub fn electrons(sensor: &Sensor, pattern: &FixedPattern, i: usize, irradiance: f32) -> f64 {
    (irradiance.max(0.0) * sensor.white_e as f32 * pattern.gain[i] + pattern.offset_e[i]) as f64
}

/// The response curve tabulated over the signal (0-1 of the full well) at this many steps and
/// interpolated linearly: within 0.01 grey levels of `signal^gamma` for any gamma used here,
/// and a look-up rather than a `powf` a pixel.
const RESPONSE_STEPS: usize = 4096;

/// Exposes and reads out an image: `irradiance` per pixel (vignetting included), `w` wide.
pub fn read_out(sensor: &Sensor, pattern: &FixedPattern, irradiance: &[f32], w: usize, seed: u64) -> Vec<u8> {
    let table = &pattern.response;
    let grey = |e: f64| {
        let t = (e / sensor.full_well_e).clamp(0.0, 1.0) * RESPONSE_STEPS as f64;
        let k = (t as usize).min(RESPONSE_STEPS - 1);
        let a = t - k as f64;
        table[k] * (1.0 - a) + table[k + 1] * a
    };
    let mut out = vec![0u8; irradiance.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        let mut rng =
            Xoshiro256PlusPlus::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(y as u64));
        for (x, o) in row.iter_mut().enumerate() {
            let i = y * w + x;
            let mean = electrons(sensor, pattern, i, irradiance[i]);
            // Shot (variance `mean`) and read noise (variance `r²`) are independent Gaussians:
            // their sum is one, of variance `mean + r²`.
            let noise: f64 = StandardNormal.sample(&mut rng);
            let e = mean + (mean + sensor.read_noise_e * sensor.read_noise_e).sqrt() * noise;
            *o = (grey(e).clamp(0.0, 255.0) + 0.5) as u8;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::realism::{Sensor, Side};

    fn linear_sensor() -> Sensor {
        let mut s = Sensor::default_for(Side::Left);
        s.gamma = 1.0;
        s
    }

    /// The variance in grey levels of a flat field at `irradiance`, over 256x256 pixels, and
    /// the same with the fixed pattern subtracted (two exposures' difference halved).
    fn temporal_variance(sensor: &Sensor, irradiance: f32) -> f64 {
        let (w, n) = (256, 256 * 256);
        let pattern = FixedPattern::new(sensor, n, 5);
        let field = vec![irradiance; n];
        let (a, b) = (read_out(sensor, &pattern, &field, w, 1), read_out(sensor, &pattern, &field, w, 2));
        let d: Vec<f64> = a.iter().zip(&b).map(|(&x, &y)| x as f64 - y as f64).collect();
        let mean = d.iter().sum::<f64>() / n as f64;
        d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64 / 2.0
    }

    #[test]
    fn noise_variance_grows_with_the_signal_as_shot_and_read_noise_predict() {
        let s = linear_sensor();
        let dn_per_e = 255.0 * s.gain / s.full_well_e;
        for irradiance in [0.1f32, 0.4, 0.8] {
            let e = irradiance as f64 * s.white_e + s.dsnu_e;
            // Shot variance e, read variance r², both scaled to grey levels, plus 1/12 for the
            // rounding to whole grey levels.
            let predicted = (e + s.read_noise_e.powi(2)) * dn_per_e * dn_per_e + 1.0 / 12.0;
            let measured = temporal_variance(&s, irradiance);
            assert!((measured / predicted - 1.0).abs() < 0.06, "at {irradiance}: {measured} vs {predicted}");
        }
    }

    #[test]
    fn gain_and_black_level_set_the_grey_levels() {
        let mut a = linear_sensor();
        a.read_noise_e = 0.0;
        a.prnu = 0.0;
        a.dsnu_e = 0.0;
        let b = Sensor { gain: a.gain * 1.08, black_level_dn: a.black_level_dn + 3.0, ..a };
        let field = vec![0.5f32; 64 * 64];
        let mean = |s: &Sensor| {
            let pattern = FixedPattern::new(s, 64 * 64, 1);
            read_out(s, &pattern, &field, 64, 3).iter().map(|&g| g as f64).sum::<f64>() / 4096.0
        };
        let (ma, mb) = (mean(&a), mean(&b));
        let ideal = |s: &Sensor| s.black_level_dn + 255.0 * s.gain * 0.5 * s.white_e / s.full_well_e;
        assert!((ma - ideal(&a)).abs() < 0.1 && (mb - ideal(&b)).abs() < 0.1, "{ma} {mb}");
        assert!((((mb - b.black_level_dn) / (ma - a.black_level_dn)) - 1.08).abs() < 0.003);
    }
}
