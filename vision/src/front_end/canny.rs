//! The Canny edge detector as MARVIN ran it: a single high-frequency scale (Gaussian sigma 1,
//! applied as a row pass then a column pass), central-difference gradients, non-maximum
//! suppression along the gradient with sub-pixel location of each edgel (a parabola through
//! the gradient magnitudes across the edge), and hysteresis between two contrast thresholds.
//! Then, beyond MARVIN, each edgel that a parallel step a few pixels away has pulled or pushed
//! is placed where its own step lies ([`CannyParams::deblur`]).

use super::blur::{Blur, step_response};
use crate::image::GreyImage;
use serde::{Deserialize, Serialize};

/// Canny's parameters. Thresholds are gradient magnitudes in grey levels per pixel.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CannyParams {
    pub sigma: f32,
    /// Edgels weaker than this are dropped.
    pub low: f32,
    /// A connected run of edgels is kept only if one of them is at least this strong.
    pub high: f32,
    /// Place edgels beside a parallel step a few pixels away where their own step lies,
    /// not where the blur of both puts the peak ([`CannyWorkspace::deblur`]). A face seen
    /// nearly edge on is a strip 2-4 px wide: sigma 1 pulls its edges 0.1-0.6 px towards each
    /// other, and the other camera, which sees the strip wider or narrower, by another
    /// amount, so their matches' disparities are off by as much. See docs/TUNING.md, "Edgels
    /// beside narrow faces" for what it gains and what it costs.
    #[serde(default = "deblur_by_default")]
    pub deblur: bool,
}

impl Default for CannyParams {
    /// `high` 2.5 grey levels per pixel, where it was 5: a face lit by ambient light alone
    /// against a table of about its grey (`worlds/side_light.toml`'s camera-facing sides, 43
    /// against 50 grey levels) makes a step of 6-7 levels, a gradient of 2.4-2.8 once smoothed,
    /// which only the low threshold let through, and only where a strong edge ran on into it:
    /// most such edges were lost, and with them the 3D lines of the parts' lower outlines. On
    /// tuning seeds (`marvin eval locate worlds/<w>.toml --seed 1`, `widgets.toml` 500 scenes,
    /// `dense.toml` and `side_light.toml` 200), 5 -> 2.5: located 96.3 / 84.6 / 83.3% -> 96.7 /
    /// 85.7 / 90.0%, false reports 21 / 33 / 19 -> 20 / 25 / 7; 2 (no hysteresis) gave 96.7 /
    /// 85.9 / 90.9% with the same false reports; 3 and 4 less (seeds 1-50).
    fn default() -> Self {
        CannyParams { sigma: 1.0, low: 2.0, high: 2.5, deblur: true }
    }
}

fn deblur_by_default() -> bool {
    true
}

/// One edge point.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Edgel {
    /// Sub-pixel position.
    pub x: f32,
    pub y: f32,
    /// Direction of the intensity gradient (from dark to bright), radians, `atan2(gy, gx)`.
    pub orientation: f32,
    /// Gradient magnitude at the edge, grey levels per pixel.
    pub contrast: f32,
    /// The smoothed image's grey level [`SIDE_PX`] to either side of the edge: on its dark side
    /// and on its bright side. What the two cameras see of one surface is alike; what lies
    /// behind a silhouette is not.
    #[serde(default)]
    pub sides: [f32; 2],
}

/// How far from the edge (pixels, across it) its sides are sampled: past the blur of a step
/// at sigma 1.
pub const SIDE_PX: f32 = 2.5;

/// The edgels of an image, and which pixel each came from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EdgeMap {
    pub width: usize,
    pub height: usize,
    pub edgels: Vec<Edgel>,
    /// Per edgel, the row-major index of the pixel it was found at.
    pub pixel: Vec<u32>,
    /// Per pixel, the index of its edgel in `edgels`, or [`NO_EDGEL`].
    pub at_pixel: Vec<u32>,
}

pub const NO_EDGEL: u32 = u32::MAX;

impl EdgeMap {
    pub fn edgel_at(&self, x: usize, y: usize) -> Option<u32> {
        let i = self.at_pixel[y * self.width + x];
        (i != NO_EDGEL).then_some(i)
    }

    /// The pixel edgel `i` was found at.
    pub fn pixel_of(&self, i: u32) -> (usize, usize) {
        let p = self.pixel[i as usize] as usize;
        (p % self.width, p / self.width)
    }

    /// An empty map for a `width` x `height` image.
    pub fn new(width: usize, height: usize) -> EdgeMap {
        let mut map = EdgeMap::default();
        map.reset(width, height);
        map
    }

    /// Drops the edgels found outside rows `rows`, in place (the same image size and pixel
    /// numbering).
    pub fn keep_rows(&mut self, rows: &std::ops::Range<usize>) {
        let width = self.width;
        self.retain(|_, pixel| rows.contains(&(pixel / width)));
    }

    /// Keeps the edgels `keep` says to (given each one's index and pixel), in order, in place.
    fn retain(&mut self, mut keep: impl FnMut(usize, usize) -> bool) {
        let mut kept = 0;
        for i in 0..self.edgels.len() {
            let p = self.pixel[i] as usize;
            if keep(i, p) {
                self.edgels[kept] = self.edgels[i];
                self.pixel[kept] = p as u32;
                self.at_pixel[p] = kept as u32;
                kept += 1;
            } else {
                self.at_pixel[p] = NO_EDGEL;
            }
        }
        self.edgels.truncate(kept);
        self.pixel.truncate(kept);
    }

    /// Empties the map for a `width` x `height` image, keeping its allocations.
    pub(crate) fn reset(&mut self, width: usize, height: usize) {
        (self.width, self.height) = (width, height);
        self.edgels.clear();
        self.pixel.clear();
        self.at_pixel.clear();
        self.at_pixel.resize(width * height, NO_EDGEL);
    }

    /// Adds an edgel found at row-major pixel `pixel`.
    pub fn push(&mut self, pixel: usize, e: Edgel) {
        self.at_pixel[pixel] = self.edgels.len() as u32;
        self.edgels.push(e);
        self.pixel.push(pixel as u32);
    }
}

/// The normalised 1D Gaussian, radius `ceil(3 sigma)`.
pub fn gaussian_kernel(sigma: f32) -> Vec<f32> {
    let r = (3.0 * sigma).ceil().max(1.0) as i32;
    let k: Vec<f32> = (-r..=r).map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp()).collect();
    let sum: f32 = k.iter().sum();
    k.into_iter().map(|v| v / sum).collect()
}

/// Buffers Canny reuses from image to image: a pipeline that sees frame after frame should
/// not pay for fresh pages each time.
#[derive(Debug, Clone, Default)]
pub struct CannyWorkspace {
    padded: Vec<f32>,
    rows: Vec<f32>,
    smoothed: Vec<f32>,
    mag: Vec<f32>,
    keep: Vec<bool>,
    stack: Vec<u32>,
}

/// Runs the detector with fresh buffers; see [`CannyWorkspace::run`] to reuse them.
pub fn canny(img: &GreyImage, params: &CannyParams) -> EdgeMap {
    let mut out = EdgeMap::default();
    CannyWorkspace::default().run(img, params, &mut out);
    out
}

impl CannyWorkspace {
    /// Runs the detector on `img`, leaving the edgels in `out`.
    pub fn run(&mut self, img: &GreyImage, params: &CannyParams, out: &mut EdgeMap) {
        self.smooth(img, params.sigma);
        self.gradients(img.width, img.height);
        self.suppress_non_maxima(img.width, img.height, params.low, out);
        self.hysteresis(out, params.high);
        if params.deblur {
            let blur = Blur::placing_in(self.extra_blur_variance(params.low, out));
            self.deblur(params.low, &blur, out);
        }
    }

    /// The smoothed gradient's magnitudes of `img` (zero on the border), for the noise tests.
    #[cfg(test)]
    pub(crate) fn gradient_magnitudes(&mut self, img: &GreyImage, sigma: f32) -> &[f32] {
        self.smooth(img, sigma);
        self.gradients(img.width, img.height);
        &self.mag
    }

    /// Gaussian smoothing by a row pass then a column pass; borders replicate the edge pixels.
    fn smooth(&mut self, img: &GreyImage, sigma: f32) {
        let (w, h) = (img.width, img.height);
        let k = gaussian_kernel(sigma);
        let r = k.len() / 2;
        fit(&mut self.rows, w * h);
        fit(&mut self.padded, w + 2 * r);
        for y in 0..h {
            let src = &img.pixels[y * w..(y + 1) * w];
            let (left, rest) = self.padded.split_at_mut(r);
            let (middle, right) = rest.split_at_mut(w);
            left.fill(src[0] as f32);
            right.fill(src[w - 1] as f32);
            middle.iter_mut().zip(src).for_each(|(p, &v)| *p = v as f32);
            let dst = &mut self.rows[y * w..(y + 1) * w];
            // Tap by tap over the whole row, so the inner loop vectorises.
            for (d, s) in dst.iter_mut().zip(&self.padded[..w]) {
                *d = k[0] * s;
            }
            for (j, kj) in k.iter().enumerate().skip(1) {
                for (d, s) in dst.iter_mut().zip(&self.padded[j..j + w]) {
                    *d += kj * s;
                }
            }
        }
        fit(&mut self.smoothed, w * h);
        for y in 0..h {
            let dst = &mut self.smoothed[y * w..(y + 1) * w];
            for (j, kj) in k.iter().enumerate() {
                let sy = (y + j).saturating_sub(r).min(h - 1);
                let src = &self.rows[sy * w..(sy + 1) * w];
                if j == 0 {
                    dst.iter_mut().zip(src).for_each(|(d, s)| *d = kj * s);
                } else {
                    dst.iter_mut().zip(src).for_each(|(d, s)| *d += kj * s);
                }
            }
        }
    }

    /// Gradient magnitudes by central differences (zero on the border).
    fn gradients(&mut self, w: usize, h: usize) {
        // Every pixel is written, the border with zeros, so a buffer left from an image of
        // another size needs no clearing first (slices differ in height).
        fit(&mut self.mag, w * h);
        if h > 0 {
            self.mag[..w].fill(0.0);
            self.mag[(h - 1) * w..].fill(0.0);
        }
        for y in 1..h.saturating_sub(1) {
            self.mag[y * w] = 0.0;
            self.mag[(y + 1) * w - 1] = 0.0;
        }
        let s = &self.smoothed;
        for y in 1..h.saturating_sub(1) {
            let (up, mid, down) = (&s[(y - 1) * w..y * w], &s[y * w..(y + 1) * w], &s[(y + 1) * w..(y + 2) * w]);
            let out = &mut self.mag[y * w + 1..(y + 1) * w - 1];
            for (x, m) in out.iter_mut().enumerate() {
                let (dx, dy) = (0.5 * (mid[x + 2] - mid[x]), 0.5 * (down[x + 1] - up[x + 1]));
                *m = (dx * dx + dy * dy).sqrt();
            }
        }
    }

    /// The gradient at pixel `i` (not on the border).
    fn gradient_at(&self, i: usize, w: usize) -> (f32, f32) {
        let s = &self.smoothed;
        (0.5 * (s[i + 1] - s[i - 1]), 0.5 * (s[i + w] - s[i - w]))
    }

    /// The smoothed grey level [`SIDE_PX`] behind and ahead of `(x, y)` along the gradient
    /// `(gx, gy)` (the nearest pixel, clamped to the image).
    fn sides_at(&self, x: f32, y: f32, gx: f32, gy: f32, w: usize, h: usize) -> [f32; 2] {
        let n = (gx * gx + gy * gy).sqrt().max(1e-6);
        let (ux, uy) = (gx / n * SIDE_PX, gy / n * SIDE_PX);
        let at = |px: f32, py: f32| {
            let xi = (px.round().max(0.0) as usize).min(w - 1);
            let yi = (py.round().max(0.0) as usize).min(h - 1);
            self.smoothed[yi * w + xi]
        };
        [at(x - ux, y - uy), at(x + ux, y + uy)]
    }

    /// Keeps pixels whose magnitude peaks across the edge, located to sub-pixel acuity.
    fn suppress_non_maxima(&self, w: usize, h: usize, low: f32, out: &mut EdgeMap) {
        out.reset(w, h);
        let mag = &self.mag;
        const RUN: usize = 16;
        for y in 2..h.saturating_sub(2) {
            let mut x = 2;
            while x < w.saturating_sub(2) {
                // Most pixels are far below threshold: skip them a run at a time.
                let run = &mag[y * w + x..(y * w + x + RUN).min((y + 1) * w - 2)];
                if run.len() == RUN && run.iter().fold(0.0f32, |a, &b| a.max(b)) < low {
                    x += RUN;
                    continue;
                }
                let i = y * w + x;
                x += 1;
                let m0 = mag[i];
                if m0 < low {
                    continue;
                }
                // Compare and fit along the one of the four pixel lines (row, column, diagonals)
                // nearest the gradient: its samples are exact, no interpolation, and for a
                // straight edge the magnitude peaks where any line across it meets it.
                let (gx, gy) = self.gradient_at(i, w);
                let (sx, sy) = nearest_pixel_line(gx, gy);
                let step = sy * w as isize + sx;
                let (behind, ahead) = (mag[(i as isize - step) as usize], mag[(i as isize + step) as usize]);
                if !(m0 >= ahead && m0 > behind) {
                    continue;
                }
                let offset = peak_offset(behind, m0, ahead);
                let (ex, ey) = ((i % w) as f32 + offset * sx as f32, y as f32 + offset * sy as f32);
                out.push(
                    i,
                    Edgel {
                        x: ex,
                        y: ey,
                        orientation: gy.atan2(gx),
                        contrast: m0 - 0.25 * (behind - ahead) * offset,
                        sides: self.sides_at(ex, ey, gx, gy, w, h),
                    },
                );
            }
        }
    }

    /// Keeps the edgels 8-connected to one of at least `high` contrast, in place.
    fn hysteresis(&mut self, map: &mut EdgeMap, high: f32) {
        let (w, h) = (map.width, map.height);
        self.keep.clear();
        self.keep.extend(map.edgels.iter().map(|e| e.contrast >= high));
        self.stack.clear();
        self.stack.extend((0..map.edgels.len() as u32).filter(|&i| self.keep[i as usize]));
        while let Some(i) = self.stack.pop() {
            let (x, y) = map.pixel_of(i);
            for (nx, ny) in neighbours(x, y, w, h) {
                let j = map.at_pixel[ny * w + nx];
                if j != NO_EDGEL && !self.keep[j as usize] {
                    self.keep[j as usize] = true;
                    self.stack.push(j);
                }
            }
        }
        map.retain(|i, _| self.keep[i]);
    }
}

/// A step beside an edgel is modelled only if it explains at least this share of the edgel's
/// own gradient (or `low`, if more): a step of a fifth of its contrast 3 px away moves it by
/// about 0.05 px.
const NEIGHBOUR_SHARE: f32 = 0.2;

/// Farthest (pixels across the edge) a neighbouring step is looked for; from 4.5 px on, the
/// blur of sigma 1 moves an edgel by under 0.05 px.
const NEIGHBOUR_REACH: f32 = 4.5;

/// Samples either side of an edgel along its pixel line that the fit reads: a step at
/// [`NEIGHBOUR_REACH`] needs one sample past its own.
const FIT_REACH: isize = 5;

/// Rounds of placing each step in turn ([`place_steps`]).
const PLACE_ROUNDS: usize = 3;

/// The pixel line across an edgel: the edge's unit normal, the line's spacing along it (pixels
/// per sample) and its step in row-major pixel indices.
struct Across {
    normal: (f32, f32),
    spacing: f32,
    step: isize,
}

impl Across {
    /// The pixel line `(sx, sy)` across the edgel at pixel `i` of a `w` x `h` image, whose
    /// gradient is `(gx, gy)`, if `reach` samples either side stay off the image's border.
    fn of(
        i: usize,
        (w, h): (usize, usize),
        (gx, gy): (f32, f32),
        (sx, sy): (isize, isize),
        reach: isize,
    ) -> Option<Across> {
        let (x, y) = ((i % w) as isize, (i / w) as isize);
        let inside =
            |v: isize, s: isize, size: usize| v - reach * s.abs() >= 1 && v + reach * s.abs() <= size as isize - 2;
        let norm = (gx * gx + gy * gy).sqrt();
        if !inside(x, sx, w) || !inside(y, sy, h) || norm <= 0.0 {
            return None;
        }
        let (c, s) = (gx / norm, gy / norm);
        Some(Across { normal: (c, s), spacing: sx as f32 * c + sy as f32 * s, step: sy * w as isize + sx })
    }
}

/// Edgels at least this many times the low threshold measure the image's blur
/// ([`CannyWorkspace::extra_blur_variance`]): their profiles stand well clear of the noise.
const MEASURES_BLUR: f32 = 4.0;

impl CannyWorkspace {
    /// How much more variance than the renderer's step the profiles across the image's edgels
    /// show ([`super::blur::measured_extra_variance`]), pixels squared: of those of at least
    /// [`MEASURES_BLUR`] times `low`; none where too few are.
    fn extra_blur_variance(&self, low: f32, out: &EdgeMap) -> Option<f32> {
        let (w, h) = (out.width, out.height);
        let profile = |i: usize| {
            let (gx, gy) = self.gradient_at(i, w);
            let across = Across::of(i, (w, h), (gx, gy), nearest_pixel_line(gx, gy), 3)?;
            let samples = std::array::from_fn(|k| self.mag[(i as isize + (k as isize - 3) * across.step) as usize]);
            Some((samples, across.spacing, across.normal))
        };
        let strong = out.edgels.iter().zip(&out.pixel).filter(|(e, _)| e.contrast >= MEASURES_BLUR * low);
        super::blur::measured_extra_variance(strong.filter_map(|(_, &i)| profile(i as usize)))
    }

    /// Moves each edgel that a parallel step a few pixels away has pulled or pushed (see
    /// [`CannyParams::deblur`]) to where its own step lies.
    fn deblur(&self, low: f32, blur: &Blur, out: &mut EdgeMap) {
        let (w, h) = (out.width, out.height);
        for (e, &i) in out.edgels.iter_mut().zip(&out.pixel) {
            let i = i as usize;
            let (gx, gy) = self.gradient_at(i, w);
            let (sx, sy) = nearest_pixel_line(gx, gy);
            let (px, py) = ((i % w) as f32, (i / w) as f32);
            let offset = ((e.x - px) * sx as f32 + (e.y - py) * sy as f32) / (sx * sx + sy * sy) as f32;
            let placed = self.offset_beside_neighbours(i, (w, h), (gx, gy), (sx, sy), offset, (low, blur));
            if placed != offset {
                (e.x, e.y) = (px + placed * sx as f32, py + placed * sy as f32);
                e.sides = self.sides_at(e.x, e.y, gx, gy, w, h);
            }
        }
    }

    /// Whether the gradient magnitudes 2 and 3 samples either side of edgel pixel `i` along
    /// its pixel line depart from one blurred step's by enough that another step may lie
    /// there: a cheap test that spares most edgels, which have none, the fit.
    fn something_beside(&self, i: usize, step: isize, spacing: f32, (low, blur): (f32, &Blur)) -> bool {
        let m0 = self.mag[i];
        let threshold = low.max(NEIGHBOUR_SHARE * m0);
        [2isize, 3].iter().any(|&k| {
            let u = k as f32 * spacing.abs();
            if u > NEIGHBOUR_REACH {
                return false;
            }
            let expected = m0 * (-u * u / (2.0 * blur.profile_variance())).exp();
            [i as isize - k * step, i as isize + k * step]
                .iter()
                .any(|&j| (self.mag[j as usize] - expected).abs() >= threshold)
        })
    }

    /// The edgel's offset along its pixel line `(sx, sy)` with a parallel step nearby taken
    /// into account: the gradients across the edge (along its normal, signed) are explained
    /// as this edgel's blurred step plus one more where what its step leaves peaks, both
    /// placed by [`place_steps`]. The old offset if nothing is there or the fit moves it by a
    /// pixel or more.
    fn offset_beside_neighbours(
        &self,
        i: usize,
        (w, h): (usize, usize),
        (gx, gy): (f32, f32),
        (sx, sy): (isize, isize),
        offset: f32,
        (low, blur): (f32, &Blur),
    ) -> f32 {
        const N: usize = (2 * FIT_REACH + 1) as usize;
        let reach = FIT_REACH;
        let Some(Across { normal: (c, s), spacing, step }) = Across::of(i, (w, h), (gx, gy), (sx, sy), reach) else {
            return offset;
        };
        if !self.something_beside(i, step, spacing, (low, blur)) {
            return offset;
        }
        let mut d = [0.0f32; N];
        let mut parallel = [true; N];
        for k in 0..N {
            let (ax, ay) = self.gradient_at((i as isize + (k as isize - reach) * step) as usize, w);
            d[k] = ax * c + ay * s;
            parallel[k] = d[k] * d[k] >= 0.81 * (ax * ax + ay * ay);
        }
        let u: [f32; N] = std::array::from_fn(|k| (k as isize - reach) as f32 * spacing);
        let row = blur.row((c, s));
        let peak = step_response(row, 0.0);
        let own = (offset * spacing, d[reach as usize] / peak);
        let residual: [f32; N] = std::array::from_fn(|k| d[k] - own.1 * step_response(row, u[k] - own.0));
        // Where the residual peaks: a step beyond the reach shows only its rising flank.
        let neighbour = (1..N - 1)
            .filter(|&k| {
                parallel[k]
                    && u[k].abs() <= NEIGHBOUR_REACH
                    && (u[k] - own.0).abs() >= 1.5
                    && residual[k].abs() >= residual[k - 1].abs()
                    && residual[k].abs() >= residual[k + 1].abs()
            })
            .max_by(|&a, &b| residual[a].abs().total_cmp(&residual[b].abs()));
        let Some(k) = neighbour else { return offset };
        if residual[k].abs() < low.max(NEIGHBOUR_SHARE * d[reach as usize].abs()) {
            return offset;
        }
        let mut steps = [own, (u[k], residual[k] / peak)];
        place_steps(&u, &d, &mut steps, row, spacing);
        let placed = steps[0].0 / spacing;
        if (placed - offset).abs() < 1.0 { placed } else { offset }
    }
}

/// The steps `(position, amplitude)` whose blurred sum best explains the samples `d` at `u`:
/// each in turn placed where what the others leave of the samples peaks (three samples round
/// it, the log-parabola of [`peak_offset`], which is exact for one step), with the amplitude
/// that explains its middle sample. Gauss-Seidel on the steps: a Gauss-Newton fit of all
/// four unknowns at once came within 0.1 point of it (matches within 0.5 px, tuning seeds)
/// and cost half as much again.
fn place_steps(u: &[f32], d: &[f32], steps: &mut [(f32, f32)], row: &[f32], spacing: f32) {
    let reach = (u.len() / 2) as isize;
    for _ in 0..PLACE_ROUNDS {
        for j in 0..steps.len() {
            let centre = (steps[j].0 / spacing).round() as isize + reach;
            if centre < 1 || centre >= 2 * reach {
                continue;
            }
            let sign = steps[j].1.signum();
            let left_by_others = |k: isize| {
                let k = k as usize;
                let others: f32 = steps
                    .iter()
                    .enumerate()
                    .filter(|&(i, _)| i != j)
                    .map(|(_, &(p, a))| a * step_response(row, u[k] - p))
                    .sum();
                sign * (d[k] - others)
            };
            let (behind, middle, ahead) =
                (left_by_others(centre - 1), left_by_others(centre), left_by_others(centre + 1));
            if middle <= 0.0 {
                continue;
            }
            let position = ((centre - reach) as f32 + peak_offset(behind, middle, ahead)) * spacing;
            let response = step_response(row, u[centre as usize] - position);
            steps[j] = (position, sign * middle / response.max(1e-3));
        }
    }
}

/// Gives `v` length `n` without clearing what it holds (every element is overwritten).
fn fit(v: &mut Vec<f32>, n: usize) {
    v.resize(n, 0.0);
}

/// Gaussian smoothing of `img` (what Canny sees), for inspection and tests.
pub fn smooth(img: &GreyImage, sigma: f32) -> Vec<f32> {
    let mut ws = CannyWorkspace::default();
    ws.smooth(img, sigma);
    ws.smoothed
}

/// Where between three equally spaced samples a peak lies, in sample spacings from the middle
/// one: a parabola through their logarithms, which is exact for a Gaussian peak (the profile
/// of a blurred step's gradient) and so avoids the bias of a plain parabola at wide spacings.
fn peak_offset(behind: f32, middle: f32, ahead: f32) -> f32 {
    let floor = 1e-3; // magnitudes can be zero far from edges; keep the logarithms finite
    let (a, m, b) = (behind.max(floor).ln(), middle.max(floor).ln(), ahead.max(floor).ln());
    let curvature = a - 2.0 * m + b;
    if curvature < 0.0 { (0.5 * (a - b) / curvature).clamp(-0.5, 0.5) } else { 0.0 }
}

/// The pixel step `(dx, dy)` of the row, column or diagonal nearest the direction `(gx, gy)`.
fn nearest_pixel_line(gx: f32, gy: f32) -> (isize, isize) {
    // tan(22.5 deg): beyond it from an axis, the diagonal is nearer.
    const TAN_22_5: f32 = 0.414_213_57;
    let (ax, ay) = (gx.abs(), gy.abs());
    if ay <= TAN_22_5 * ax {
        (1, 0)
    } else if ax <= TAN_22_5 * ay {
        (0, 1)
    } else {
        (1, if (gx > 0.0) == (gy > 0.0) { 1 } else { -1 })
    }
}

/// The 8-neighbours of `(x, y)` inside a `w` x `h` image.
pub fn neighbours(x: usize, y: usize, w: usize, h: usize) -> impl Iterator<Item = (usize, usize)> {
    (-1i32..=1)
        .flat_map(|dy| (-1i32..=1).map(move |dx| (dx, dy)))
        .filter(|&d| d != (0, 0))
        .map(move |(dx, dy)| (x as i32 + dx, y as i32 + dy))
        .filter(move |&(nx, ny)| nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h)
        .map(|(nx, ny)| (nx as usize, ny as usize))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An image whose grey level depends on the signed distance from the line through
    /// `through` with normal at `angle`, each pixel the exact mean over its square (by
    /// `samples` x `samples` supersampling), so edges sit at known sub-pixel places.
    fn banded_image(
        size: usize,
        (angle, through): (f32, (f32, f32)),
        samples: usize,
        level: impl Fn(f32) -> f32,
    ) -> GreyImage {
        let (nx, ny) = (angle.cos(), angle.sin());
        let n = samples as f32;
        let pixels = (0..size * size)
            .map(|i| {
                let (px, py) = ((i % size) as f32, (i / size) as f32);
                let mut sum = 0.0;
                for sy in 0..samples {
                    for sx in 0..samples {
                        let (x, y) = (px - 0.5 + (sx as f32 + 0.5) / n, py - 0.5 + (sy as f32 + 0.5) / n);
                        sum += level(nx * (x - through.0) + ny * (y - through.1));
                    }
                }
                (sum / (n * n)).round() as u8
            })
            .collect();
        GreyImage::new(size, size, pixels).unwrap()
    }

    /// Two grey levels split by the line `n . (p - c) = 0`.
    fn step_image(size: usize, angle: f32, through: (f32, f32), dark: f32, bright: f32) -> GreyImage {
        banded_image(size, (angle, through), 64, |d| if d > 0.0 { bright } else { dark })
    }

    fn rms_distance(map: &EdgeMap, angle: f32, through: (f32, f32), size: usize) -> (f64, usize) {
        let (nx, ny) = (angle.cos(), angle.sin());
        let inner: Vec<f64> = map
            .edgels
            .iter()
            .filter(|e| e.x > 6.0 && e.y > 6.0 && e.x < size as f32 - 7.0 && e.y < size as f32 - 7.0)
            .map(|e| (nx * (e.x - through.0) + ny * (e.y - through.1)) as f64)
            .collect();
        ((inner.iter().map(|d| d * d).sum::<f64>() / inner.len().max(1) as f64).sqrt(), inner.len())
    }

    /// Three grey levels in bands: `levels[0]` before the line through `through` with normal
    /// at `angle`, `levels[1]` for `width` pixels after it, `levels[2]` beyond.
    fn strip_image(size: usize, angle: f32, through: (f32, f32), levels: [f32; 3], width: f32) -> GreyImage {
        banded_image(size, (angle, through), 32, |d| {
            if d < 0.0 {
                levels[0]
            } else if d < width {
                levels[1]
            } else {
                levels[2]
            }
        })
    }

    /// The mean signed distance of the edgels of `img` within half of `width` of the line
    /// through `through` with normal at `angle`, away from the image's border.
    fn mean_offset(img: &GreyImage, params: &CannyParams, angle: f32, through: (f32, f32), width: f32) -> f32 {
        let (nx, ny) = (angle.cos(), angle.sin());
        let d: Vec<f32> = canny(img, params)
            .edgels
            .iter()
            .filter(|e| e.x > 8.0 && e.y > 8.0 && e.x < 32.0 && e.y < 32.0)
            .map(|e| nx * (e.x - through.0) + ny * (e.y - through.1))
            .filter(|d| d.abs() < width / 2.0)
            .collect();
        assert!(d.len() >= 10, "only {} edgels", d.len());
        d.iter().sum::<f32>() / d.len() as f32
    }

    #[test]
    fn deblurring_places_an_edge_beside_a_narrow_strip_where_it_lies() {
        let blurred = CannyParams { deblur: false, ..CannyParams::default() };
        // A staircase (a face seen nearly edge on between two others), a bright bar, and a
        // dark strip with a weaker step beyond, at several angles and sub-pixel places.
        for (levels, width, blur_moves_it) in [
            ([60.0f32, 120.0, 180.0], 3.0f32, true),
            ([60.0, 120.0, 180.0], 3.5, true),
            ([60.0, 160.0, 60.0], 2.5, true),
            ([60.0, 160.0, 60.0], 3.0, true),
            ([150.0, 60.0, 90.0], 2.5, true),
            ([60.0, 120.0, 180.0], 5.0, false),
        ] {
            let mut worst = (0.0f32, 0.0f32);
            for (angle, offset) in [(0.0f32, 0.0f32), (0.0, 0.3), (0.4, 0.17), (1.1, 0.71), (0.785, 0.2), (2.5, 0.42)] {
                let through = (20.0 + offset, 20.0 + offset / 2.0);
                let img = strip_image(40, angle, through, levels, width);
                let plain = mean_offset(&img, &blurred, angle, through, width);
                let placed = mean_offset(&img, &CannyParams::default(), angle, through, width);
                worst = (worst.0.max(plain.abs()), worst.1.max(placed.abs()));
            }
            eprintln!("{levels:?} width {width}: plain {:.3} px, deblurred {:.3} px off", worst.0, worst.1);
            assert!(
                worst.1 < 0.08 && worst.1 < 0.5 * worst.0.max(0.1),
                "{levels:?} width {width}: deblurred {:.3} px off",
                worst.1
            );
            // The blur alone moves the edge by more where the strip is narrow; where it is
            // wide there is nothing to take out, and deblurring leaves the edge as it was.
            if blur_moves_it {
                assert!(worst.0 > 0.1, "{levels:?} width {width}: plain only {:.3} px off", worst.0);
            } else {
                assert!((worst.0 - worst.1).abs() < 0.01, "{levels:?} width {width}: moved");
            }
        }
    }

    /// A unit step blurred by a Gaussian of `sigma` pixels (none at 0), at signed distance `d`.
    fn blurred_step(d: f32, sigma: f32) -> f32 {
        if sigma <= 0.0 { f32::from(d > 0.0) } else { 0.5 * (1.0 + libm::erff(d / (sigma * std::f32::consts::SQRT_2))) }
    }

    /// The extra blur's variance Canny measures in `img` (pixels squared).
    fn measured_extra_variance(img: &GreyImage) -> f32 {
        let params = CannyParams::default();
        let mut ws = CannyWorkspace::default();
        let mut map = EdgeMap::default();
        ws.smooth(img, params.sigma);
        ws.gradients(img.width, img.height);
        ws.suppress_non_maxima(img.width, img.height, params.low, &mut map);
        ws.hysteresis(&mut map, params.high);
        ws.extra_blur_variance(params.low, &map).unwrap_or(0.0)
    }

    #[test]
    fn an_image_blurrier_than_the_renderer_is_measured_so() {
        for extra_sigma in [0.0f32, 0.45, 0.8, 1.2] {
            for (angle, offset) in [(0.0f32, 0.3f32), (0.4, 0.17), (0.785, 0.2), (2.5, 0.42)] {
                let through = (32.0 + offset, 32.0 + offset / 2.0);
                let img = banded_image(64, (angle, through), 16, |d| 60.0 + 120.0 * blurred_step(d, extra_sigma));
                let measured = measured_extra_variance(&img);
                let truth = extra_sigma * extra_sigma;
                eprintln!("extra sigma {extra_sigma}, angle {angle}: variance {measured:.3} against {truth:.3}");
                assert!(
                    (measured - truth).abs() < 0.08 + 0.05 * truth,
                    "angle {angle}: {measured:.3} against {truth:.3}"
                );
            }
        }
    }

    #[test]
    fn deblurring_leaves_edges_of_a_blurrier_image_where_they_lie() {
        // A lens blurrier than the renderer's (extra sigma 1.2 px) widens every edge's profile;
        // taken for the renderer's, that looks like a neighbouring step beside each edgel.
        let extra_sigma = 1.2f32;
        for (angle, offset) in [(0.0f32, 0.0f32), (0.0, 0.3), (0.4, 0.17), (1.1, 0.71), (0.785, 0.2), (2.5, 0.42)] {
            let through = (32.0 + offset, 32.0 + offset / 2.0);
            let img = banded_image(64, (angle, through), 16, |d| 60.0 + 120.0 * blurred_step(d, extra_sigma));
            let map = canny(&img, &CannyParams::default());
            let (rms, n) = rms_distance(&map, angle, through, 64);
            eprintln!("angle {angle}, offset {offset}: rms {rms:.4} px over {n}");
            assert!(n >= 40 && rms < 0.05, "angle {angle}, offset {offset}: rms {rms:.3} px over {n}");
        }
    }

    #[test]
    fn the_kernel_is_a_normalised_gaussian() {
        let k = gaussian_kernel(1.0);
        assert_eq!(k.len(), 7);
        assert!((k.iter().sum::<f32>() - 1.0).abs() < 1e-6);
        assert!((k[3] / k[4] - 0.5f32.exp()).abs() < 1e-5);
    }

    #[test]
    fn straight_edges_are_located_to_a_twentieth_of_a_pixel() {
        for (angle, offset) in
            [(0.0f32, 0.0f32), (0.0, 0.3), (0.0, 0.5), (0.4, 0.17), (1.1, 0.71), (0.785, 0.2), (2.5, 0.42), (2.5, 0.1)]
        {
            let through = (16.0 + offset, 16.0 + offset / 2.0);
            let img = step_image(32, angle, through, 60.0, 180.0);
            let map = canny(&img, &CannyParams::default());
            let (rms, n) = rms_distance(&map, angle, through, 32);
            assert!(n >= 15, "angle {angle}: only {n} edgels");
            eprintln!("angle {angle}, offset {offset}: rms {rms:.4} px over {n}");
            assert!(rms < 0.05, "angle {angle}, offset {offset}: rms {rms:.3} px");
        }
    }

    #[test]
    fn orientation_points_from_dark_to_bright_and_contrast_scales() {
        let img = step_image(32, 0.4, (16.0, 16.0), 60.0, 180.0);
        let map = canny(&img, &CannyParams::default());
        let e = map.edgels.iter().find(|e| (e.x - 16.0).abs() < 3.0 && (e.y - 16.0).abs() < 3.0).unwrap();
        assert!((e.orientation - 0.4).abs() < 0.05, "orientation {}", e.orientation);
        // A 120 grey-level step, blurred by the pixel (variance 1/12) and the Gaussian (1), seen
        // by a central difference: 120 (Phi(1/s) - Phi(-1/s)) / 2 = 60 erf(1 / (s sqrt 2)), s^2 = 13/12,
        // which is 39.8.
        assert!((e.contrast - 39.8).abs() < 2.0, "contrast {}", e.contrast);
    }

    #[test]
    fn flat_images_have_no_edges() {
        let img = GreyImage::new(40, 40, vec![90; 1600]).unwrap();
        assert!(canny(&img, &CannyParams::default()).edgels.is_empty());
    }
}
