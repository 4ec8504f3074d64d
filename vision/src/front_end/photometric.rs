//! The pair's photometric relation, measured from its own matches: the right camera's grey
//! levels as the left camera would have recorded them.
//!
//! PMF compares the grey levels beside an edgel across the pair ([`super::pmf`]), which holds
//! only when both cameras turn the same light into the same grey level. Real cameras differ in
//! gain, black level and response (the realistic cell's right camera reads 10-15 grey levels
//! above its left at mid grey). The relation is measured as MARVIN's cell would have to:
//! PMF first matches without comparing the sides; where both cameras see one surface beside a
//! matched edgel, its two grey levels are a sample of the relation; a line fitted to them with
//! the outliers (the far side of silhouettes, where the backgrounds differ) cut away is the
//! relation, and the right edgels' grey levels are mapped through it before PMF matches again.
//! Where the cameras are alike it comes out as the identity to within the sensor noise.

use super::canny::Edgel;

/// `left_grey = gain * right_grey + offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relation {
    pub gain: f32,
    pub offset: f32,
}

impl Relation {
    pub const IDENTITY: Relation = Relation { gain: 1.0, offset: 0.0 };

    /// A right edgel as the left camera would have recorded it: its sides' grey levels mapped,
    /// its contrast scaled.
    pub fn map(&self, e: &Edgel) -> Edgel {
        Edgel { sides: e.sides.map(|s| self.gain * s + self.offset), contrast: e.contrast * self.gain, ..*e }
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

/// The relation from the sides of matched edgels (`(left, right)` indices into `left`,
/// `right`): both sides of every match, a line fitted with the outliers cut.
pub fn from_matches(left: &[Edgel], right: &[Edgel], matches: impl Iterator<Item = (u32, u32)>) -> Relation {
    let samples: Vec<(f32, f32)> = matches
        .flat_map(|(l, r)| {
            let (l, r) = (&left[l as usize], &right[r as usize]);
            [(r.sides[0], l.sides[0]), (r.sides[1], l.sides[1])]
        })
        .collect();
    fit(&samples)
}

/// A line `y = gain x + offset` through `(x, y)` samples, robust to a minority of outliers.
pub fn fit(samples: &[(f32, f32)]) -> Relation {
    if samples.len() < MIN_SAMPLES {
        return Relation::IDENTITY;
    }
    // Start from the offset alone (gain 1), which the outliers move least.
    let mut relation = Relation { gain: 1.0, offset: median(samples.iter().map(|(x, y)| y - x).collect()) };
    for _ in 0..ROUNDS {
        let residual = |&(x, y): &(f32, f32)| y - (relation.gain * x + relation.offset);
        let spread = 1.4826 * median(samples.iter().map(|s| residual(s).abs()).collect());
        let cut = (CUT_DEVIATIONS * spread).max(MIN_CUT);
        let kept: Vec<(f32, f32)> = samples.iter().copied().filter(|s| residual(s).abs() <= cut).collect();
        match least_squares(&kept) {
            Some(r) if kept.len() >= MIN_SAMPLES => relation = r,
            _ => break,
        }
    }
    relation
}

fn least_squares(samples: &[(f32, f32)]) -> Option<Relation> {
    let n = samples.len() as f64;
    let (mx, my) = samples.iter().fold((0.0, 0.0), |(a, b), &(x, y)| (a + x as f64 / n, b + y as f64 / n));
    let (sxx, sxy) = samples.iter().fold((0.0, 0.0), |(a, b), &(x, y)| {
        let (dx, dy) = (x as f64 - mx, y as f64 - my);
        (a + dx * dx, b + dx * dy)
    });
    // Samples bunched at one grey level say nothing of the gain.
    (sxx > n * 25.0).then(|| {
        let gain = sxy / sxx;
        Relation { gain: gain as f32, offset: (my - gain * mx) as f32 }
    })
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

    /// Side samples of the realistic cell's right sensor against its left (written out here:
    /// right = 1.05 left + 3.3, with half a grey level of noise), a quarter of them outliers
    /// (another surface behind a silhouette): the fit gives back the relation.
    #[test]
    fn the_relation_comes_back_from_samples_with_outliers() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let samples: Vec<(f32, f32)> = (0..600)
            .map(|k| {
                let left: f32 = rng.random_range(20.0..220.0);
                let right = 1.05 * left + 3.3 + rng.random_range(-0.5..0.5);
                let seen = if k % 4 == 0 { rng.random_range(0.0..255.0) } else { left };
                (right, seen)
            })
            .collect();
        let r = fit(&samples);
        assert!((r.gain - 1.0 / 1.05).abs() < 0.01, "{r:?}");
        assert!((r.gain * 120.0 + r.offset - (120.0 - 3.3) / 1.05).abs() < 0.5, "{r:?}");
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
        assert!((r.gain - 1.0).abs() < 0.005 && r.offset.abs() < 0.5, "{r:?}");
        assert_eq!(fit(&samples[..100]), Relation::IDENTITY, "too few samples");
    }
}
