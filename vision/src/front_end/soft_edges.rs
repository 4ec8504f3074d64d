//! Shadows and texture are not parts (issue 48, part 3): 3D lines on the table's top whose
//! edges are soft are set apart, and the matcher does not build on them.
//!
//! A part's edge is a step in the image as sharp as the lens and Canny's sigma make it: at the
//! edgel the gradient is a fixed share of the step across it. A shadow cast by a lamp of some
//! size has a penumbra, and the table's texture varies smoothly: across both the grey level
//! climbs over more pixels, and the gradient is a smaller share of the step. Both lie on the
//! table's top, with no depth step; so do the parts' bottom edges, but those are as sharp as
//! any other edge of a part.
//!
//! The sharpness is measured against the image's own: the median over its strongest steps,
//! which are mostly parts' edges. So a camera with another lens, focus or blur is judged by
//! its own standard, not by the renderer's.

use super::canny::Edgel;
use super::lines3d::Line3;
use super::workspace::Table;

/// A line is soft where its edgels' median sharpness is below this share of the image's.
///
/// Chosen on realistic tuning seeds 1-30 (`marvin eval vision --hand-eye`; docs/TUNING.md,
/// "Shadows and texture set apart"). On `widgets.toml` the lines on the table and on no part's
/// edge had a median sharpness of 0.26 (0.30 at the 90th percentile), the parts' bottom edges
/// 0.32 (0.28 at the 10th), the image's about 0.33. At 0.85 of the image's, 0.92 of the lines
/// set apart are on no part's edge and 0.63 of such lines on the table are set apart (dense:
/// 0.88 and 0.68); at 0.80, 0.96 and 0.44; at 0.90, 0.89 and 0.77 with more of the parts'
/// edges lost (coverage 0.7395 -> 0.7384 at 0.85, 0.7372 at 0.90).
pub const SOFT_SHARE: f64 = 0.85;

/// Both ends of a line within this distance (metres) of the table's top: on it.
pub const ON_TABLE_M: f64 = 0.004;

/// Edgels whose step across them (bright side less dark side, grey levels) is at least this
/// and in the image's top quarter set the image's sharpness.
const STRONG_STEP_GREY: f32 = 8.0;

/// Below this step (grey levels) an edgel's sharpness is noise.
const MIN_STEP_GREY: f32 = 1.0;

/// An edgel's sharpness: its gradient (grey levels per pixel) as a share of the step across it.
fn sharpness(e: &Edgel) -> Option<f64> {
    let step = e.sides[1] - e.sides[0];
    (step >= MIN_STEP_GREY).then(|| (e.contrast / step) as f64)
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// The image's sharpness: the median over its edgels with the strongest steps (the top
/// quarter, and at least [`STRONG_STEP_GREY`]).
pub fn image_sharpness(edgels: &[Edgel]) -> Option<f64> {
    let mut steps: Vec<f32> = edgels.iter().map(|e| e.sides[1] - e.sides[0]).collect();
    if steps.is_empty() {
        return None;
    }
    steps.sort_by(f32::total_cmp);
    let strong = steps[steps.len() * 3 / 4].max(STRONG_STEP_GREY);
    median(edgels.iter().filter(|e| e.sides[1] - e.sides[0] >= strong).filter_map(sharpness).collect())
}

/// A 3D line's sharpness: the median over the edgels that carried it (none for a line
/// completed from its neighbours).
pub fn line_sharpness(line: &Line3, edgels: &[Edgel]) -> Option<f64> {
    median(line.inliers.iter().filter_map(|&i| edgels.get(i as usize)).filter_map(sharpness).collect())
}

/// Whether `line` lies on the table's top and its edges are soft, against the image's
/// sharpness `image`.
pub fn is_soft_on_table(line: &Line3, edgels: &[Edgel], image: f64, table: &Table) -> bool {
    let on_table = [line.start(), line.end()].iter().all(|p| table.height_of(p).abs() <= ON_TABLE_M);
    on_table && line_sharpness(line, edgels).is_some_and(|s| s < SOFT_SHARE * image)
}

/// `lines` split into those not soft on `table`'s top and those that are, judged by the left
/// image's (rectified) `edgels` (the lines' inliers index them).
pub fn split(lines: Vec<Line3>, edgels: &[Edgel], table: &Table) -> (Vec<Line3>, Vec<Line3>) {
    let Some(image) = image_sharpness(edgels) else { return (lines, Vec::new()) };
    lines.into_iter().partition(|l| !is_soft_on_table(l, edgels, image, table))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::canny::{CannyParams, canny};
    use crate::image::GreyImage;

    /// A vertical step from grey 60 to 160 across `width` pixels (a ramp; 0 for a sharp step
    /// as the renderer's box filter leaves it), in a 64 x 64 image.
    fn step(width: f64) -> GreyImage {
        let pixels = (0..64 * 64)
            .map(|i| {
                let x = (i % 64) as f64 + 0.5 - 32.0;
                let t = if width == 0.0 { f64::from(u8::from(x > 0.0)) } else { (x / width + 0.5).clamp(0.0, 1.0) };
                (60.0 + 100.0 * t).round() as u8
            })
            .collect();
        GreyImage::new(64, 64, pixels).unwrap()
    }

    fn median_sharpness(img: &GreyImage) -> f64 {
        let edges = canny(img, &CannyParams::default());
        median(edges.edgels.iter().filter_map(sharpness).collect()).unwrap()
    }

    /// A sharp step's sharpness is the Gaussian's (sigma 1: about 0.4 of the step per pixel,
    /// less as the sides are sampled 2.5 px out); a penumbra 4 px wide is well under the
    /// share of it that [`SOFT_SHARE`] asks.
    #[test]
    fn a_soft_step_is_less_sharp_than_a_sharp_one() {
        let sharp = median_sharpness(&step(0.0));
        let soft = median_sharpness(&step(4.0));
        assert!((0.3..0.45).contains(&sharp), "a sharp step: {sharp:.3}");
        assert!(soft < SOFT_SHARE * sharp, "a 4 px penumbra: {soft:.3} against {sharp:.3}");
        let slightly = median_sharpness(&step(1.0));
        assert!(slightly > SOFT_SHARE * sharp, "a 1 px ramp (the lens's blur): {slightly:.3} against {sharp:.3}");
    }
}
