//! The pair's photometric relation, measured from its own matches: the right camera's grey
//! levels as the left camera would have recorded them.
//!
//! PMF compares the grey levels beside an edgel across the pair ([`super::pmf`]), which holds
//! only when both cameras turn the same light into the same grey level. Real cameras differ in
//! gain, black level and response (the realistic cell's right camera reads 10-15 grey levels
//! above its left at mid grey). The relation is measured as MARVIN's cell would have to:
//! PMF first matches without comparing the sides; where both cameras see one surface beside a
//! matched edgel, its two grey levels are a sample of the relation; a curve fitted to them with
//! the outliers (the far side of silhouettes, where the backgrounds differ) cut away is the
//! relation, and the right edgels' grey levels are mapped through it before PMF matches again.
//! Where the cameras are alike it comes out as the identity to within the sensor noise.
//! How far the inliers scatter about the curve, by grey level ([`Scatter`]), tells PMF how
//! alike one surface's two grey levels can be asked to be in this pair.
//!
//! The curve is a quadratic, not a line: two sensors whose responses differ (grey level as
//! `signal^gamma`, gammas 1.0 and 0.85) relate their grey levels by a power, which a line
//! misses by several grey levels at the ends of the range, beyond PMF's side tolerance. On
//! realistic `widgets.toml` tuning scenes lit by other lamps and imaged so, the line lost 0.022
//! of the 3D edge length (`marvin eval vision`, coverage 0.686 with equal gammas, 0.664).

use super::canny::Edgel;
use nalgebra::{Matrix3, Vector3};

/// `left_grey = f(right_grey)`: a quadratic over the grey levels it was fitted on, continued
/// beyond them along its tangent (a quadratic far from its samples bends anywhere).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relation {
    /// `f(x) = c[0] + c[1] x + c[2] x^2` on `range`.
    c: [f32; 3],
    range: (f32, f32),
    /// How far one surface's two grey levels scatter about the curve.
    pub scatter: Scatter,
}

/// How far the grey levels of one surface, seen by both cameras, scatter about the relation
/// (a robust standard deviation, grey levels), by the left camera's grey level: shot noise
/// grows with the light, and so do a glossy face's highlight and a lens's fall-off, which
/// differ between two cameras that see the face from two places. Measured on the inliers of
/// the fit, in [`SCATTER_BANDS`] bands of grey level; zero where not measured.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Scatter {
    by_band: [f32; SCATTER_BANDS],
}

/// Bands of grey level (256 / SCATTER_BANDS levels each) the scatter is measured in.
pub const SCATTER_BANDS: usize = 8;
/// Fewest inlier samples in a band for its own scatter; a band with fewer takes all bands'.
const MIN_BAND_SAMPLES: usize = 40;

impl Scatter {
    /// The same scatter at every grey level.
    pub fn uniform(deviation: f32) -> Scatter {
        Scatter { by_band: [deviation; SCATTER_BANDS] }
    }

    /// The scatter at left grey level `grey`, between the bands' middles.
    pub fn at(&self, grey: f32) -> f32 {
        let width = 256.0 / SCATTER_BANDS as f32;
        let t = (grey / width - 0.5).clamp(0.0, (SCATTER_BANDS - 1) as f32);
        let (k, a) = (t.floor() as usize, t.fract());
        let next = (k + 1).min(SCATTER_BANDS - 1);
        self.by_band[k] * (1.0 - a) + self.by_band[next] * a
    }

    /// The scatter of `(right, left)` inlier samples about `relation`.
    fn measure(samples: &[(f32, f32)], relation: &Relation) -> Scatter {
        let width = 256.0 / SCATTER_BANDS as f32;
        let mut bands: Vec<Vec<f32>> = vec![Vec::new(); SCATTER_BANDS];
        for &(x, y) in samples {
            let band = ((y / width).max(0.0) as usize).min(SCATTER_BANDS - 1);
            bands[band].push((y - relation.grey(x)).abs());
        }
        let all = 1.4826 * median(bands.concat());
        let mut by_band = [all; SCATTER_BANDS];
        for (s, band) in by_band.iter_mut().zip(bands) {
            if band.len() >= MIN_BAND_SAMPLES {
                *s = 1.4826 * median(band);
            }
        }
        Scatter { by_band }
    }
}

impl Relation {
    pub const IDENTITY: Relation =
        Relation { c: [0.0, 1.0, 0.0], range: (0.0, 255.0), scatter: Scatter { by_band: [0.0; SCATTER_BANDS] } };

    /// The line `gain x + offset`.
    pub fn linear(gain: f32, offset: f32) -> Relation {
        Relation { c: [offset, gain, 0.0], ..Relation::IDENTITY }
    }

    /// A right grey level as the left camera would have recorded it.
    pub fn grey(&self, x: f32) -> f32 {
        let inside = x.clamp(self.range.0, self.range.1);
        let [c0, c1, c2] = self.c;
        c0 + c1 * inside + c2 * inside * inside + self.slope(inside) * (x - inside)
    }

    /// The relation's slope at grey level `x`.
    pub fn slope(&self, x: f32) -> f32 {
        let inside = x.clamp(self.range.0, self.range.1);
        self.c[1] + 2.0 * self.c[2] * inside
    }

    /// A right edgel as the left camera would have recorded it: its sides' grey levels mapped,
    /// its contrast scaled by the slope between them (for a quadratic, the mapped step exactly).
    pub fn map(&self, e: &Edgel) -> Edgel {
        let between = 0.5 * (e.sides[0] + e.sides[1]);
        Edgel { sides: e.sides.map(|s| self.grey(s)), contrast: e.contrast * self.slope(between), ..*e }
    }
}

/// Fewest side samples (two a match) the relation is fitted from; with fewer, the identity. A
/// few edges cannot tell a difference of gain from different surfaces (one edge whose sides
/// are both unlike is another edge, or the same one seen by another sensor); a slice of a
/// scene gives some 200-400 matches.
const MIN_SAMPLES: usize = 200;
/// Residuals beyond this many robust deviations (and at least `MIN_CUT` grey levels) are
/// outliers: a side one camera sees and the other does not.
const CUT_DEVIATIONS: f32 = 3.0;
const MIN_CUT: f32 = 2.0;
/// Fit, cut, fit again this many times.
const ROUNDS: usize = 3;
/// The curve must rise at least this steeply everywhere on its range: both cameras' grey
/// levels grow with the light. A fit that does not is a line instead.
const MIN_SLOPE: f32 = 0.2;

/// The relation from the sides of matched edgels (`(left, right)` indices into `left`,
/// `right`): both sides of every match, a curve fitted with the outliers cut.
pub fn from_matches(left: &[Edgel], right: &[Edgel], matches: impl Iterator<Item = (u32, u32)>) -> Relation {
    let samples: Vec<(f32, f32)> = matches
        .flat_map(|(l, r)| {
            let (l, r) = (&left[l as usize], &right[r as usize]);
            [(r.sides[0], l.sides[0]), (r.sides[1], l.sides[1])]
        })
        .collect();
    fit(&samples)
}

/// A rising curve `y = f(x)` through `(x, y)` samples, robust to a minority of outliers.
pub fn fit(samples: &[(f32, f32)]) -> Relation {
    if samples.len() < MIN_SAMPLES {
        return Relation::IDENTITY;
    }
    // Start from the offset alone (gain 1), which the outliers move least.
    let mut relation = Relation::linear(1.0, median(samples.iter().map(|(x, y)| y - x).collect()));
    for _ in 0..ROUNDS {
        let kept = inliers(samples, &relation);
        match least_squares(&kept) {
            Some(r) if kept.len() >= MIN_SAMPLES => relation = r,
            _ => break,
        }
    }
    relation.scatter = Scatter::measure(&inliers(samples, &relation), &relation);
    relation
}

/// The samples within [`CUT_DEVIATIONS`] robust deviations of `relation` (and `MIN_CUT`).
fn inliers(samples: &[(f32, f32)], relation: &Relation) -> Vec<(f32, f32)> {
    let residual = |&(x, y): &(f32, f32)| y - relation.grey(x);
    let spread = 1.4826 * median(samples.iter().map(|s| residual(s).abs()).collect());
    let cut = (CUT_DEVIATIONS * spread).max(MIN_CUT);
    samples.iter().copied().filter(|s| residual(s).abs() <= cut).collect()
}

/// The least-squares quadratic through the samples, or the line where the quadratic does not
/// rise over their range; `None` where the samples bunch at one grey level.
fn least_squares(samples: &[(f32, f32)]) -> Option<Relation> {
    let n = samples.len() as f64;
    let mean = samples.iter().map(|s| s.0 as f64).sum::<f64>() / n;
    let spread = samples.iter().map(|s| (s.0 as f64 - mean).powi(2)).sum::<f64>();
    // Samples bunched at one grey level say nothing of the gain.
    if spread <= n * 25.0 {
        return None;
    }
    let range = samples.iter().fold((f32::MAX, f32::MIN), |(lo, hi), s| (lo.min(s.0), hi.max(s.0)));
    // In grey levels about the mean, scaled, for a well-conditioned 3x3 system.
    const SCALE: f64 = 100.0;
    let (mut a, mut b) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
    for &(x, y) in samples {
        let t = (x as f64 - mean) / SCALE;
        let row = Vector3::new(1.0, t, t * t);
        a += row * row.transpose();
        b += row * y as f64;
    }
    let from_centred = |k: [f64; 3]| {
        // k0 + k1 t + k2 t^2 with t = (x - mean) / SCALE, as powers of x.
        let (s, m) = (SCALE, mean);
        let c2 = k[2] / (s * s);
        let c1 = k[1] / s - 2.0 * k[2] * m / (s * s);
        let c0 = k[0] - k[1] * m / s + k[2] * m * m / (s * s);
        Relation { c: [c0 as f32, c1 as f32, c2 as f32], range, scatter: Scatter::default() }
    };
    let quadratic = a.lu().solve(&b).map(|k| from_centred([k[0], k[1], k[2]]));
    let rises = |r: &Relation| r.slope(range.0).min(r.slope(range.1)) >= MIN_SLOPE;
    match quadratic {
        Some(q) if rises(&q) => Some(q),
        _ => {
            let k1 = samples.iter().map(|&(x, y)| (x as f64 - mean) * y as f64).sum::<f64>() / spread * SCALE;
            let k0 = samples.iter().map(|s| s.1 as f64).sum::<f64>() / n;
            Some(from_centred([k0, k1, 0.0]))
        }
    }
}

fn median(mut v: Vec<f32>) -> f32 {
    if v.is_empty() {
        return 0.0;
    }
    let k = v.len() / 2;
    *v.select_nth_unstable_by(k, f32::total_cmp).1
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{RngExt, SeedableRng};

    /// Side samples: a left grey level drawn over 20-220, the right camera's `right_of(left)`
    /// with half a grey level of noise; every fourth an outlier (another surface behind a
    /// silhouette, seen by the left camera alone).
    fn samples(seed: u64, n: usize, right_of: impl Fn(f32) -> f32) -> Vec<(f32, f32)> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        (0..n)
            .map(|k| {
                let left: f32 = rng.random_range(20.0..220.0);
                let right = right_of(left) + rng.random_range(-0.5..0.5);
                let seen = if k % 4 == 0 { rng.random_range(0.0..255.0) } else { left };
                (right, seen)
            })
            .collect()
    }

    /// The most the relation is off the true one's inverse over the samples' range.
    fn worst(r: &Relation, right_of: impl Fn(f32) -> f32) -> f32 {
        (20..=220).map(|l| (r.grey(right_of(l as f32)) - l as f32).abs()).fold(0.0, f32::max)
    }

    /// The realistic cell's right sensor against its left (written out here: right = 1.05
    /// left + 3.3): the fit gives back the relation, outliers and all.
    #[test]
    fn the_relation_comes_back_from_samples_with_outliers() {
        let right_of = |l: f32| 1.05 * l + 3.3;
        let r = fit(&samples(7, 600, right_of));
        assert!(worst(&r, right_of) < 0.5, "{r:?}");
        assert!((r.slope(120.0) - 1.0 / 1.05).abs() < 0.01, "{r:?}");
    }

    /// Two sensors of different response (grey level as `signal^gamma`: the right's gamma 0.85
    /// where the left's is 1.0, its gain 1.12 and black level 14 against 0.95 and 6): the fit
    /// gives the curve back to within half PMF's side tolerance (3 grey levels; a quadratic
    /// misses the power by 1.2 at the darkest end), where the best line misses it by more than
    /// the whole tolerance at the ends of the range.
    #[test]
    fn a_different_response_comes_back_as_a_curve() {
        let right_of = |l: f32| {
            let signal = (l - 6.0) / (255.0 * 0.95);
            14.0 + 255.0 * 1.12 * signal.powf(0.85)
        };
        let s = samples(9, 800, right_of);
        let r = fit(&s);
        assert!(worst(&r, right_of) < 1.5, "{r:?} off by {}", worst(&r, right_of));
        // The line through the same inliers, for comparison.
        let inliers: Vec<(f32, f32)> = s.iter().copied().filter(|&(x, y)| (r.grey(x) - y).abs() < 2.0).collect();
        let n = inliers.len() as f32;
        let (mx, my) = inliers.iter().fold((0.0, 0.0), |(a, b), &(x, y)| (a + x / n, b + y / n));
        let (sxx, sxy) =
            inliers.iter().fold((0.0, 0.0), |(a, b), &(x, y)| (a + (x - mx).powi(2), b + (x - mx) * (y - my)));
        let line = Relation::linear(sxy / sxx, my - sxy / sxx * mx);
        assert!(worst(&line, right_of) > 3.0, "the line would do: off by {}", worst(&line, right_of));
    }

    /// Alike cameras: the identity, to within the noise.
    #[test]
    fn alike_cameras_give_the_identity() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(8);
        let samples: Vec<(f32, f32)> = (0..400)
            .map(|_| {
                let g: f32 = rng.random_range(20.0..220.0);
                (g + rng.random_range(-0.5..0.5), g)
            })
            .collect();
        let r = fit(&samples);
        assert!(worst(&r, |l| l) < 0.5 && (r.slope(120.0) - 1.0).abs() < 0.01, "{r:?}");
        assert_eq!(fit(&samples[..100]), Relation::IDENTITY, "too few samples");
    }

    /// Noise that grows with the light (a deviation of 0.5 + 0.02 x the grey level) comes
    /// back as the scatter at each grey level, outliers and all; too few samples, none.
    #[test]
    fn the_scatter_comes_back_by_grey_level() {
        let deviation = |g: f32| 0.5 + 0.02 * g;
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        let samples: Vec<(f32, f32)> = (0..3000)
            .map(|k| {
                let left: f32 = rng.random_range(10.0..245.0);
                // Near-Gaussian: the sum of four uniforms, scaled to the deviation.
                let unit: f32 = (0..4).map(|_| rng.random_range(-1.0f32..1.0)).sum::<f32>() * (3.0f32 / 4.0).sqrt();
                let right = 1.05 * (left + deviation(left) * unit) + 3.3;
                let seen = if k % 5 == 0 { rng.random_range(0.0..255.0) } else { left };
                (right, seen)
            })
            .collect();
        let r = fit(&samples);
        for g in [40.0, 120.0, 200.0] {
            let (got, want) = (r.scatter.at(g), deviation(g));
            assert!((got - want).abs() < 0.25 * want, "at {g}: {got} against {want}");
        }
        assert_eq!(fit(&samples[..100]).scatter, Scatter::default());
    }

    /// Beyond the grey levels it was fitted on, the curve goes on along its tangent and keeps
    /// rising; a mapped edgel's contrast is its mapped step.
    #[test]
    fn the_curve_goes_on_straight_and_maps_an_edgel_step_for_step() {
        let right_of = |l: f32| 255.0 * (l / 255.0).powf(0.8);
        let r = fit(&samples(11, 800, right_of));
        let (hi, beyond) = (r.grey(250.0), r.grey(300.0));
        assert!((beyond - hi - 50.0 * r.slope(250.0)).abs() < 1e-2, "{hi} {beyond}");
        assert!(r.grey(0.0) < r.grey(10.0) && r.slope(0.0) > 0.0);
        let e = Edgel { x: 0.0, y: 0.0, orientation: 0.0, sides: [60.0, 140.0], contrast: 80.0 };
        let m = r.map(&e);
        assert!((m.contrast - (m.sides[1] - m.sides[0])).abs() < 0.05, "{m:?}");
    }
}
