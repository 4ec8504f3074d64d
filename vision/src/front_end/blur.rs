//! The blur of the image Canny sees, for placing edgels beside parallel steps
//! ([`super::canny::CannyParams::deblur`]): how a blurred step's gradient looks across it, and
//! how much blurrier than the project's renderer an image is, measured from its own strongest
//! edgels (issue 48, part 2).
//!
//! Why measured: the placement explains the gradients across an edgel as its own blurred step
//! plus a neighbour's. With the renderer's blur assumed, a lens blurrier than the project's
//! (a Gaussian PSF of 1.2 px where the project's is 0.45) widens every edge's profile, the cheap
//! test finds "something beside" nearly every edgel, and the fit moves each by up to a pixel,
//! differently in the two images: on tuning seeds 1-100 of `widgets.toml` with such lenses,
//! `marvin eval locate` located 0.78 of the parts, 0.95 with the placement off, and 0.95 with
//! the blur measured (docs/TUNING.md, session 67).

use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

/// Effective blur (pixels, a Gaussian's sigma) of a rendered step before the central
/// differences: Canny's Gaussian (sigma 1) and the pixel's area (a box, variance 1/12).
const STEP_BLUR: f64 = 1.040_833;

/// Variance of a rendered step's gradient profile: the Gaussian (1), the pixel's area (1/12)
/// and the central difference (1/3), as a Gaussian for the cheap test of
/// [`super::canny::CannyWorkspace`]'s placement.
const PROFILE_VARIANCE: f32 = 1.0 + 1.0 / 12.0 + 1.0 / 3.0;

/// An image's blur as the placement models it: the renderer's, plus a measured variance
/// (pixels squared) that the image's own edges show beyond it.
#[derive(Clone)]
pub(crate) struct Blur {
    extra_variance: f32,
    table: Arc<ResponseTable>,
}

/// Blur this much beyond the renderer's step (a variance, pixels squared) is left out of the
/// placement's model: the placement was chosen on the realistic cell's images, whose edges
/// show 0.2-0.45 more (its lenses' PSF of 0.45 px, 0.2, and their defocus), and with the
/// renderer's step. Modelling those images' blur in full lost 7 of 2074 parts and made 3 false
/// reports more on tuning seeds 1-300 of `widgets.toml`; leaving out 0.25, 0.4 or 0.6 lost
/// 0-2 (docs/TUNING.md, session 67). A lens blurrier than the cell's is modelled by what it
/// adds beyond this.
const PLACED_AS_TUNED: f32 = 0.25;

/// Measured extra variances are rounded to this (pixels squared), so that the few tables the
/// images need are built once and shared.
const VARIANCE_STEP: f32 = 0.02;
/// The modelled extra variance goes no higher than this (pixels squared): an image blurred by
/// more than 2 px is modelled as blurred by 2.
const MAX_EXTRA_VARIANCE: f32 = 4.0;

impl Blur {
    /// The project's renderer's blur: the placement as it was first made.
    pub(crate) fn of_renderer() -> Blur {
        Blur::with_extra_variance(0.0)
    }

    /// The blur the placement models in an image whose edges show `measured` variance beyond
    /// the renderer's step (pixels squared; none measured, the renderer's): what lies beyond
    /// [`PLACED_AS_TUNED`].
    pub(crate) fn placing_in(measured: Option<f32>) -> Blur {
        Blur::with_extra_variance(measured.map_or(0.0, |m| (m - PLACED_AS_TUNED).max(0.0)))
    }

    /// The renderer's blur and `extra` more (pixels squared; rounded to [`VARIANCE_STEP`]).
    fn with_extra_variance(extra: f32) -> Blur {
        static TABLES: OnceLock<Mutex<HashMap<i32, Arc<ResponseTable>>>> = OnceLock::new();
        let extra = extra.clamp(0.0, MAX_EXTRA_VARIANCE);
        let key = (extra / VARIANCE_STEP).round() as i32;
        let extra_variance = key as f32 * VARIANCE_STEP;
        let tables = TABLES.get_or_init(Default::default);
        let mut tables = tables.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let table = tables
            .entry(key)
            .or_insert_with(|| Arc::new(ResponseTable::new((STEP_BLUR * STEP_BLUR + f64::from(extra_variance)).sqrt())))
            .clone();
        Blur { extra_variance, table }
    }

    /// Variance of a step's gradient profile across it, pixels squared, as a Gaussian's.
    pub(crate) fn profile_variance(&self) -> f32 {
        PROFILE_VARIANCE + self.extra_variance
    }

    /// A unit step's central-difference gradient along the normal `(c, s)`, tabulated by the
    /// signed distance `u` from the step: pass to [`step_response`].
    pub(crate) fn row(&self, (c, s): (f32, f32)) -> &[f32] {
        self.table.row((c, s))
    }
}

/// The extra variance an image's edges show beyond the renderer's, pixels squared, from
/// `profiles`: for each strong edgel, its gradient magnitudes from three samples behind it to
/// three ahead along its pixel line, the line's spacing across the edge (pixels per sample)
/// and the edge's normal. A profile that does not fall away from the edgel all the way out
/// on both sides has another step beside it, and is left out. Each other's width is the
/// log-parabola's through the samples two behind, at, and two ahead (exact for a Gaussian,
/// whatever the edgel's sub-pixel place), less the width the renderer's step would show along
/// the same line; the median of at least [`MIN_PROFILES`] of them, else none.
pub(crate) fn measured_extra_variance(profiles: impl Iterator<Item = ([f32; 7], f32, (f32, f32))>) -> Option<f32> {
    let renderer = Blur::of_renderer();
    let width = |[behind, at, ahead]: [f32; 3], spacing: f32| {
        let curvature = behind.ln() + ahead.ln() - 2.0 * at.ln();
        (curvature < 0.0).then(|| -4.0 * spacing * spacing / curvature)
    };
    let mut extra: Vec<f32> = profiles
        .filter(|(m, ..)| m.iter().all(|&v| v > 0.0) && m[..4].is_sorted() && m[3..].is_sorted_by(|a, b| a >= b))
        .filter_map(|(m, spacing, normal)| {
            let m = [m[1], m[3], m[5]];
            let row = renderer.row(normal);
            let u = 2.0 * spacing;
            let model = [step_response(row, -u), step_response(row, 0.0), step_response(row, u)];
            Some(width(m, spacing)? - width(model, spacing)?)
        })
        .collect();
    if extra.len() < MIN_PROFILES {
        return None;
    }
    let mid = extra.len() / 2;
    Some(*extra.select_nth_unstable_by(mid, f32::total_cmp).1)
}

/// Fewer strong edgels than this measure no blur (a slice of table alone): the renderer's is
/// assumed.
const MIN_PROFILES: usize = 40;

/// Central-difference gradient along the normal `(c, s)` (absolute values) of a unit step at
/// signed distance `u` blurred by a Gaussian of `sigma`, exactly: each difference spans two
/// pixels, `c` and `s` of them across the edge.
fn step_response_exact(u: f64, (c, s): (f64, f64), sigma: f64) -> f64 {
    let cdf = |t: f64| 0.5 * (1.0 + libm::erf(t / (sigma * std::f64::consts::SQRT_2)));
    let part = |a: f64| a * (cdf(u + a) - cdf(u - a));
    0.5 * (part(c) + part(s))
}

/// [`step_response_exact`] tabulated: by the normal's angle from the nearer axis (0-45 deg;
/// the response is symmetric in `c` and `s`) and by `u` out to [`RESPONSE_REACH`] pixels.
struct ResponseTable {
    values: Vec<f32>,
}

const RESPONSE_REACH: f32 = 8.0;
const RESPONSE_PER_PX: usize = 32;
const RESPONSE_ANGLES: usize = 16;
const RESPONSE_ROW: usize = 2 * RESPONSE_REACH as usize * RESPONSE_PER_PX + 1;

impl ResponseTable {
    fn new(sigma: f64) -> ResponseTable {
        let mut values = Vec::with_capacity((RESPONSE_ANGLES + 1) * RESPONSE_ROW);
        for a in 0..=RESPONSE_ANGLES {
            let angle = std::f64::consts::FRAC_PI_4 * a as f64 / RESPONSE_ANGLES as f64;
            for k in 0..RESPONSE_ROW {
                let u = k as f64 / RESPONSE_PER_PX as f64 - RESPONSE_REACH as f64;
                values.push(step_response_exact(u, (angle.cos(), angle.sin()), sigma) as f32);
            }
        }
        ResponseTable { values }
    }

    /// The row for the normal `(c, s)`.
    fn row(&self, (c, s): (f32, f32)) -> &[f32] {
        let angle = c.abs().min(s.abs()).atan2(c.abs().max(s.abs()));
        let a = ((angle / std::f32::consts::FRAC_PI_4 * RESPONSE_ANGLES as f32).round() as usize).min(RESPONSE_ANGLES);
        &self.values[a * RESPONSE_ROW..(a + 1) * RESPONSE_ROW]
    }
}

/// A unit step's response at `u` from a [`Blur::row`] (zero beyond its reach).
pub(crate) fn step_response(row: &[f32], u: f32) -> f32 {
    let t = (u + RESPONSE_REACH) * RESPONSE_PER_PX as f32;
    if t < 0.0 || t >= (row.len() - 1) as f32 {
        return 0.0;
    }
    let k = t as usize;
    row[k] + (t - k as f32) * (row[k + 1] - row[k])
}
