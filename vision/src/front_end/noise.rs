//! The image's own noise, and Canny's thresholds above it (issue 48, part 2): a camera's noise
//! is measured in each image, not assumed, and each threshold is raised where that noise would
//! pass it.

use super::canny::{CannyParams, gaussian_kernel};
use crate::image::GreyImage;

/// The low threshold is at least this many standard deviations of the smoothed gradient's
/// noise (one component's): a noise-only pixel's gradient magnitude (Rayleigh) passes it with
/// probability exp(-3.72^2 / 2) = 1e-3...
pub const NOISE_LOW_SD: f32 = 3.72;
/// ...and the high threshold this many (1e-5): a run of edgels no stronger than noise is then
/// all but never kept. Set from those rates, not tuned.
pub const NOISE_HIGH_SD: f32 = 4.80;

impl CannyParams {
    /// These parameters for `img`: each threshold raised, where the image's own noise
    /// ([`noise_sigma`]) would let noise through it, to [`NOISE_LOW_SD`] and [`NOISE_HIGH_SD`]
    /// standard deviations of the gradient's noise ([`gradient_noise_gain`]); never lowered.
    /// A camera of a fifth of the noise leaves them as they are (the project's sensors, whose
    /// images show 1-2 grey levels, do); a noisier one, or an image of much fine texture,
    /// raises them.
    pub fn for_image(&self, img: &GreyImage) -> CannyParams {
        let sd = noise_sigma(img) * gradient_noise_gain(self.sigma);
        CannyParams { low: self.low.max(NOISE_LOW_SD * sd), high: self.high.max(NOISE_HIGH_SD * sd), ..*self }
    }
}

/// The standard deviation of an image's noise (grey levels), by Immerkaer's estimator ("Fast
/// noise variance estimation", 1996): the mean absolute response to the difference of two
/// Laplacians, which cancels any image that is locally a plane, scaled to a standard deviation
/// for Gaussian noise. Edges add to it a little; fine texture counts as noise, which is what
/// the thresholds should ignore.
pub fn noise_sigma(img: &GreyImage) -> f32 {
    let (w, h) = (img.width, img.height);
    if w < 3 || h < 3 {
        return 0.0;
    }
    let p = |x: usize, y: usize| i32::from(img.pixels[y * w + x]);
    let mut sum: u64 = 0;
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let corners = p(x - 1, y - 1) + p(x + 1, y - 1) + p(x - 1, y + 1) + p(x + 1, y + 1);
            let sides = p(x, y - 1) + p(x - 1, y) + p(x + 1, y) + p(x, y + 1);
            sum += (corners - 2 * sides + 4 * p(x, y)).unsigned_abs() as u64;
        }
    }
    let n = ((w - 2) * (h - 2)) as f64;
    ((std::f64::consts::FRAC_PI_2).sqrt() * sum as f64 / (6.0 * n)) as f32
}

/// The standard deviation of one component of the smoothed gradient (grey levels per pixel)
/// per grey level of white noise: the Gaussian of `sigma` across, and its central difference
/// along, as [`CannyWorkspace`] computes them.
pub fn gradient_noise_gain(sigma: f32) -> f32 {
    let k = gaussian_kernel(sigma);
    let across: f32 = k.iter().map(|v| v * v).sum();
    let along: f32 = (0..k.len() + 2)
        .map(|i| {
            let at = |j: usize| if j >= 1 && j <= k.len() { k[j - 1] } else { 0.0 };
            0.5 * (at(i + 2) - at(i))
        })
        .map(|d| d * d)
        .sum();
    (across * along).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::canny::canny;
    use rand::{RngExt, SeedableRng};

    /// Gaussian noise of standard deviation `sd` (Box-Muller), seeded.
    fn gaussian(rng: &mut rand::rngs::StdRng, sd: f64) -> f64 {
        let (u, v): (f64, f64) = (rng.random::<f64>().max(1e-12), rng.random());
        sd * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }

    /// A 256 x 256 image: a dark square on a lighter ground (a step of 60 grey levels) under a
    /// gentle ramp, with Gaussian noise of `sd` grey levels.
    fn square(sd: f64, seed: u64) -> GreyImage {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let pixels = (0..256 * 256)
            .map(|i| {
                let (x, y) = (i % 256, i / 256);
                let inside = (80..176).contains(&x) && (80..176).contains(&y);
                let level = if inside { 90.0 } else { 150.0 } + 0.1 * x as f64;
                (level + gaussian(&mut rng, sd)).round().clamp(0.0, 255.0) as u8
            })
            .collect();
        GreyImage::new(256, 256, pixels).unwrap()
    }

    #[test]
    fn the_noise_is_measured_in_the_image() {
        for sd in [2.0, 5.0, 10.0] {
            let got = noise_sigma(&square(sd, 7)) as f64;
            assert!((got - sd).abs() < 0.1 * sd + 0.3, "noise {sd}: measured {got:.2}");
        }
        // A plane and a step, no noise: what remains is the step's few pixels.
        assert!(noise_sigma(&square(0.0, 7)) < 0.5);
    }

    /// The gain against the gradient Canny computes: white noise through it, the magnitudes'
    /// mean is the Rayleigh mean of the gain times the noise.
    #[test]
    fn the_gradient_noise_gain_is_what_cannys_gradient_does_to_noise() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let sd = 20.0;
        let pixels = (0..256 * 256).map(|_| (128.0 + gaussian(&mut rng, sd)).round().clamp(0.0, 255.0) as u8).collect();
        let img = GreyImage::new(256, 256, pixels).unwrap();
        let mut ws = crate::front_end::canny::CannyWorkspace::default();
        let magnitudes = ws.gradient_magnitudes(&img, 1.0);
        let inner: Vec<f32> =
            (8..248).flat_map(|y| (8..248).map(move |x| (x, y))).map(|(x, y)| magnitudes[y * 256 + x]).collect();
        let mean = inner.iter().map(|m| *m as f64).sum::<f64>() / inner.len() as f64;
        let predicted = gradient_noise_gain(1.0) as f64 * sd * (std::f64::consts::FRAC_PI_2).sqrt();
        assert!((mean - predicted).abs() < 0.03 * predicted, "mean {mean:.3}, predicted {predicted:.3}");
    }

    /// Under noise of 6 grey levels the default thresholds let noise through as edgels all
    /// over the image; raised above the image's noise, Canny keeps the square's outline and
    /// little else. A clean image keeps the default thresholds.
    #[test]
    fn thresholds_above_the_images_noise_keep_the_edges_and_drop_the_noise() {
        let noisy = square(6.0, 11);
        let params = CannyParams::default();
        let raised = params.for_image(&noisy);
        assert!(raised.low > params.low && raised.high > params.high, "{raised:?}");
        let off_the_outline = |edges: &crate::front_end::canny::EdgeMap| {
            edges
                .edgels
                .iter()
                .filter(|e| [80.0, 176.0].iter().all(|b| (e.x + 0.5 - b).abs() > 3.0 && (e.y + 0.5 - b).abs() > 3.0))
                .count()
        };
        let (by_default, by_noise) = (canny(&noisy, &params), canny(&noisy, &raised));
        assert!(off_the_outline(&by_default) > 1000, "{} edgels of noise", off_the_outline(&by_default));
        assert!(off_the_outline(&by_noise) < 50, "{} edgels of noise", off_the_outline(&by_noise));
        // The outline: 4 sides of 96 px, most of it found.
        assert!(by_noise.edgels.len() - off_the_outline(&by_noise) > 300);
        assert_eq!(params.for_image(&square(1.0, 11)), params, "a clean image keeps the defaults");
    }
}
