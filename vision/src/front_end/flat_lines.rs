//! Lines along the rasters, matched whole between the images.
//!
//! PMF matches no edgel within 20 deg of the rasters (`PmfParams::min_angle_to_raster`): along
//! a rectified row such an edgel's partner could lie anywhere on the right image's nearly
//! parallel edge. Those lines carry a third of a part's visible edges (`marvin eval vision
//! worlds/dense.toml`, tuning seeds 1-20: 28% of the visible feature-edge length, of which 3D
//! lines recovered 43% against 78% of the rest), and [`super::lines3d::complete_flat_lines`]
//! gives one 3D ends only where 3D lines meet it at both ends, which a part half hidden in a
//! pile seldom has.
//!
//! A whole line is better placed than any of its edgels. Fitted over its edgels, a left line
//! and a right line give `x = a + b y` each; where both are images of one 3D edge, rows are
//! epipolars, so the disparity at row `y` is the difference of their `x` there, and a straight
//! 3D edge has a disparity linear in `y` between them. The two are taken for one edge where they
//! run through the same rows, with the same contrast sign, at disparities the workspace allows
//! (not under the table), changing no faster along the line than a part's edge can, and where
//! no other line of either image would do as well (a pair is kept only if each is the other's
//! one candidate). Lines within [`MIN_ANGLE`] of the rasters are left: their rows are too few
//! for the difference to say anything.

use super::canny::Edgel;
use super::lines2d::{Line2, Lines2dParams, fit_lines};
use super::lines3d::{Depths, Line3};
use super::pmf::{PmfParams, angle_diff};
use super::rectify::Rectification;
use super::strings::EdgeString;
use super::workspace::DisparityPlane;

/// Lines nearer the rasters than PMF's `min_angle_to_raster` carry no PMF match, and are the
/// ones matched here...
fn flat_angle() -> f32 {
    PmfParams::default().min_angle_to_raster
}
/// ...unless nearer still than this (radians): over a line's few rows the difference of two lines' `x`
/// goes as the error of their slopes over the sine of this angle.
pub const MIN_ANGLE: f32 = 0.08;
/// Shortest line matched, pixels.
pub const MIN_LENGTH_PX: f32 = 15.0;
/// The rows both lines run through, as a share of the rows of the shorter.
const MIN_ROW_OVERLAP: f32 = 0.6;
/// Fastest change of disparity along the left line, pixels per pixel.
const MAX_DISPARITY_GRADIENT: f32 = 0.25;
/// Largest turn (radians) between the two lines' mean gradient directions: the same contrast
/// sign, and a direction alike.
const MAX_GRADIENT_TURN: f32 = 0.5;
/// The right image's lines considered run a little beyond the left band: a 3D edge's two images
/// lean differently where its depth changes along it.
const RIGHT_ANGLE_SLACK: f32 = 0.1;
/// The standard deviation of a matched line's disparity at its ends, pixels (for `Line3`'s
/// depth sigmas).
const END_DISPARITY_SIGMA_PX: f64 = 0.3;

/// A line of one image as a function of the row: `x = a + b y` over rows `y0..=y1`, with its
/// edgels' mean gradient direction.
#[derive(Debug, Clone, Copy)]
struct RowLine {
    a: f64,
    b: f64,
    y0: f64,
    y1: f64,
    gradient: f32,
}

impl RowLine {
    fn of(line: &Line2, string: &EdgeString, edgels: &[Edgel], (min, max): (f32, f32)) -> Option<RowLine> {
        let dir = line.direction();
        let sin = dir[1].abs();
        if line.length() < MIN_LENGTH_PX || sin < min.sin() || sin >= max.sin() {
            return None;
        }
        let (dx, dy) = ((line.end[0] - line.start[0]) as f64, (line.end[1] - line.start[1]) as f64);
        let b = dx / dy;
        let a = line.start[0] as f64 - b * line.start[1] as f64;
        let (s, c) = string.edgels[line.first as usize..=line.last as usize]
            .iter()
            .map(|&i| edgels[i as usize].orientation)
            .fold((0.0f32, 0.0f32), |(s, c), o| (s + o.sin(), c + o.cos()));
        let (y0, y1) = (line.start[1].min(line.end[1]) as f64, line.start[1].max(line.end[1]) as f64);
        Some(RowLine { a, b, y0, y1, gradient: s.atan2(c) })
    }

    fn x_at(&self, y: f64) -> f64 {
        self.a + self.b * y
    }
}

/// The rows both lines of a match run through, first and last, each with its disparity.
type Ends = [(f64, f64); 2];

/// The disparity search: its range, and the floor under the table where that is known.
pub type Search = (f32, f32, Option<DisparityPlane>);

/// The rows both lines run through and the disparity at each end of them, if `right` could
/// be `left`'s partner.
fn disparities(left: &RowLine, right: &RowLine, (min, max, floor): &Search) -> Option<Ends> {
    if angle_diff(left.gradient, right.gradient) > MAX_GRADIENT_TURN {
        return None;
    }
    let (y0, y1) = (left.y0.max(right.y0), left.y1.min(right.y1));
    let shorter = (left.y1 - left.y0).min(right.y1 - right.y0);
    if y1 - y0 < MIN_ROW_OVERLAP as f64 * shorter || y1 <= y0 {
        return None;
    }
    let ends = [y0, y1].map(|y| (y, left.x_at(y) - right.x_at(y)));
    let allowed = |&(y, d): &(f64, f64)| {
        let x = left.x_at(y);
        d >= *min as f64 && d <= *max as f64 && floor.is_none_or(|f| d >= f.at(x as f32, y as f32) as f64)
    };
    let along = ((left.x_at(y1) - left.x_at(y0)).powi(2) + (y1 - y0).powi(2)).sqrt();
    let gradient = (ends[1].1 - ends[0].1).abs() / along.max(1.0);
    (ends.iter().all(allowed) && gradient <= MAX_DISPARITY_GRADIENT as f64).then_some(ends)
}

/// What the front end has of both images for [`match_flat_lines`]: the left image's 2D lines,
/// and each image's strings and rectified edgels.
pub struct Images<'a> {
    pub lines2d: &'a [Line2],
    pub left_strings: &'a [EdgeString],
    pub left_rectified: &'a [Edgel],
    pub right_strings: &'a [EdgeString],
    pub right_rectified: &'a [Edgel],
}

/// 3D lines for the left 2D lines along the rasters, each matched whole with a right image
/// line ([`self`]), added to `lines3d`. A line completed from the lines meeting its corners is
/// matched too, and where it is, the whole match replaces the completion: a corner may be
/// another part's, at another depth (`marvin eval vision worlds/dense.toml`, tuning seeds 1-20:
/// of the completed lines, 34% lay with their middle more than 5 mm from every true edge, of the
/// whole matches 4%).
pub fn match_flat_lines(images: &Images, rect: &Rectification, search: &Search, lines3d: &mut Vec<Line3>) {
    let right = right_row_lines(images);
    let left = left_row_lines(images, lines3d);
    let added: Vec<Line3> = one_to_one(&left, &right, search)
        .into_iter()
        .map(|(k, ends)| {
            let (li, row) = &left[k];
            line3_of(&images.lines2d[*li], *li, row, ends, rect)
        })
        .collect();
    let mut replaced = vec![false; images.lines2d.len()];
    for l in &added {
        replaced[l.line2 as usize] = true;
    }
    lines3d.retain(|l| l.depths != Depths::Corners || !replaced[l.line2 as usize]);
    lines3d.extend(added);
}

/// The right image's lines near the rasters, as functions of the row.
fn right_row_lines(images: &Images) -> Vec<RowLine> {
    let (strings, edgels) = (images.right_strings, images.right_rectified);
    let band = (MIN_ANGLE - RIGHT_ANGLE_SLACK / 2.0, flat_angle() + RIGHT_ANGLE_SLACK);
    fit_lines(edgels, strings, &Lines2dParams::default())
        .iter()
        .filter_map(|l| RowLine::of(l, &strings[l.string as usize], edgels, band))
        .collect()
}

/// The left 2D lines near the rasters with no 3D line of their own (none, or one completed
/// from its corners), each with its index.
fn left_row_lines(images: &Images, lines3d: &[Line3]) -> Vec<(usize, RowLine)> {
    let mut has_own = vec![false; images.lines2d.len()];
    for l in lines3d.iter().filter(|l| l.depths != Depths::Corners) {
        has_own[l.line2 as usize] = true;
    }
    images
        .lines2d
        .iter()
        .enumerate()
        .filter(|(i, _)| !has_own[*i])
        .filter_map(|(i, l)| {
            let string = &images.left_strings[l.string as usize];
            Some((i, RowLine::of(l, string, images.left_rectified, (MIN_ANGLE, flat_angle()))?))
        })
        .collect()
}

/// The (left index, disparities) of each left line whose one candidate among `right` has it as
/// its own one candidate.
fn one_to_one(left: &[(usize, RowLine)], right: &[RowLine], search: &Search) -> Vec<(usize, Ends)> {
    let candidates: Vec<Vec<(usize, Ends)>> = left
        .iter()
        .map(|(_, l)| right.iter().enumerate().filter_map(|(j, r)| Some((j, disparities(l, r, search)?))).collect())
        .collect();
    let mut takers = vec![0usize; right.len()];
    for (j, _) in candidates.iter().flatten() {
        takers[*j] += 1;
    }
    candidates
        .into_iter()
        .enumerate()
        .filter_map(|(li, c)| match c.as_slice() {
            [(j, ends)] if takers[*j] == 1 => Some((li, *ends)),
            _ => None,
        })
        .collect()
}

/// The 3D line of left line `line` (index `li`) between the rows of `ends`, at their disparities.
fn line3_of(line: &Line2, li: usize, row: &RowLine, ends: Ends, rect: &Rectification) -> Line3 {
    // Ends in the left line's own order.
    let ends = if line.start[1] <= line.end[1] { ends } else { [ends[1], ends[0]] };
    let [a, b] = ends.map(|(y, d)| rect.triangulate(row.x_at(y), y, d));
    let sigma = |d: f64| rect.f * rect.baseline * END_DISPARITY_SIGMA_PX / (d * d);
    Line3 {
        a: [a.x, a.y, a.z],
        b: [b.x, b.y, b.z],
        sigma_a: sigma(ends[0].1),
        sigma_b: sigma(ends[1].1),
        disparity_start: ends[0].1,
        disparity_end: ends[1].1,
        line2: li as u32,
        matches: 0,
        depths: Depths::WholeLine,
        inliers: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::canny::EdgeMap;
    use crate::front_end::rectify::tests::verged_pair;
    use crate::front_end::strings::{MIN_STRING, link_strings};
    use nalgebra::Point3;

    /// A segment given in the rectified frame (metres), as the `cam` frame has it.
    fn in_cam(rect: &Rectification, p: [f64; 3]) -> Point3<f64> {
        Point3::from(rect.rect_from_left.inverse() * nalgebra::Vector3::from(p))
    }

    /// Edgels one pixel apart (in x) along the image line from `a` to `b` (rectified pixels),
    /// each a pixel of `map`, with a small deterministic wobble across the line.
    fn draw(map: &mut EdgeMap, a: [f64; 2], b: [f64; 2]) {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        let gradient = (dy.atan2(dx) + std::f64::consts::FRAC_PI_2) as f32;
        let steps = dx.abs().round() as usize;
        for k in 0..=steps {
            let t = k as f64 / steps as f64;
            let wobble = 0.04 * (((k * 7) % 5) as f64 - 2.0);
            let (x, y) = (a[0] + t * dx, a[1] + t * dy + wobble);
            let e = Edgel { x: x as f32, y: y as f32, orientation: gradient, contrast: 20.0, sides: [60.0, 120.0] };
            map.push(y.round() as usize * map.width + x.round() as usize, e);
        }
    }

    /// Where a point of the rectified frame appears: rectified left x, y and its disparity.
    fn seen(rect: &Rectification, p: [f64; 3]) -> ([f64; 2], f64) {
        let (x, y) = (rect.f * p[0] / p[2] + rect.cx, rect.f * p[1] / p[2] + rect.cy);
        ([x, y], rect.f * rect.baseline / p[2])
    }

    /// What the front end found of the left and right image lines drawn (given already
    /// rectified): strings, rectified edgels and the left 2D lines.
    struct Found {
        lines2d: Vec<Line2>,
        left: (Vec<EdgeString>, Vec<Edgel>),
        right: (Vec<EdgeString>, Vec<Edgel>),
    }

    impl Found {
        fn of(left: &[Segment], right: &[Segment]) -> Found {
            let strings_of = |lines: &[Segment]| {
                let mut map = EdgeMap::new(512, 512);
                for &(a, b) in lines {
                    draw(&mut map, a, b);
                }
                (link_strings(&map, MIN_STRING), map.edgels)
            };
            let (left, right) = (strings_of(left), strings_of(right));
            Found { lines2d: fit_lines(&left.1, &left.0, &Lines2dParams::default()), left, right }
        }

        /// [`match_flat_lines`] on these, after `lines3d`.
        fn matched(&self, rect: &Rectification, search: &Search, mut lines3d: Vec<Line3>) -> Vec<Line3> {
            let images = Images {
                lines2d: &self.lines2d,
                left_strings: &self.left.0,
                left_rectified: &self.left.1,
                right_strings: &self.right.0,
                right_rectified: &self.right.1,
            };
            match_flat_lines(&images, rect, search, &mut lines3d);
            lines3d
        }
    }

    /// An image line's ends, rectified pixels.
    type Segment = ([f64; 2], [f64; 2]);

    /// The 3D edge from `a` to `b` (rectified frame, metres) as both images show it.
    fn images_of(rect: &Rectification, a: [f64; 3], b: [f64; 3]) -> (Segment, Segment) {
        let ((la, da), (lb, db)) = (seen(rect, a), seen(rect, b));
        ((la, lb), ([la[0] - da, la[1]], [lb[0] - db, lb[1]]))
    }

    fn distance_to_segment(p: &Point3<f64>, a: &Point3<f64>, b: &Point3<f64>) -> f64 {
        let ab = b - a;
        let t = ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
        (p - (a + ab * t)).norm()
    }

    const SEARCH: Search = (125.0, 333.0, None);

    /// An edge 8 deg off the rasters, 0.9-0.93 m away, which PMF cannot match edgel by edgel:
    /// the two image lines through the same rows place it within a millimetre.
    #[test]
    fn an_edge_along_the_rasters_is_placed_from_its_two_image_lines() {
        let rect = Rectification::new(&verged_pair());
        let (a, b) = ([-0.03, 0.01, 0.90], [0.03, 0.019, 0.93]);
        let (left, right) = images_of(&rect, a, b);
        let found = Found::of(&[left], &[right]);
        assert_eq!(found.lines2d.len(), 1, "{:?}", found.lines2d);
        let lines3d = found.matched(&rect, &SEARCH, Vec::new());
        assert_eq!(lines3d.len(), 1);
        let l = &lines3d[0];
        assert_eq!(l.depths, Depths::WholeLine);
        let (ta, tb) = (in_cam(&rect, a), in_cam(&rect, b));
        for end in [l.start(), l.end()] {
            let off = distance_to_segment(&end, &ta, &tb);
            assert!(off < 1e-3, "an end {:.2} mm off the edge", off * 1e3);
        }
        assert!((l.end() - l.start()).norm() > 0.9 * (tb - ta).norm(), "{l:?}");
    }

    /// Where the right image has two lines that could each be the partner (two parallel edges
    /// 3 px apart across the rows, both at workspace disparities), nothing is guessed.
    #[test]
    fn a_line_with_two_partners_is_left_alone() {
        let rect = Rectification::new(&verged_pair());
        let (left, right) = images_of(&rect, [-0.03, 0.01, 0.90], [0.03, 0.019, 0.93]);
        let shifted = ([right.0[0], right.0[1] + 3.0], [right.1[0], right.1[1] + 3.0]);
        let lines3d = Found::of(&[left], &[right, shifted]).matched(&rect, &SEARCH, Vec::new());
        assert!(lines3d.is_empty(), "{lines3d:?}");
    }

    /// A partner of the other contrast sign (a dark-to-bright edge where the left shows
    /// bright-to-dark) or at a disparity the workspace rules out is no partner.
    #[test]
    fn a_partner_of_the_other_contrast_or_out_of_the_workspace_is_refused() {
        let rect = Rectification::new(&verged_pair());
        let (left, right) = images_of(&rect, [-0.03, 0.01, 0.90], [0.03, 0.019, 0.93]);
        let mut turned = Found::of(&[left], &[right]);
        for e in &mut turned.right.1 {
            e.orientation += std::f32::consts::PI;
        }
        let lines3d = turned.matched(&rect, &SEARCH, Vec::new());
        assert!(lines3d.is_empty(), "{lines3d:?}");
        let lines3d = Found::of(&[left], &[right]).matched(&rect, &(230.0, 333.0, None), Vec::new());
        assert!(lines3d.is_empty(), "{lines3d:?}");
    }

    /// A line completed wrongly from the lines at its corners (one of them another part's, at
    /// another depth) is replaced by its whole match.
    #[test]
    fn the_whole_match_replaces_a_line_completed_from_its_corners() {
        let rect = Rectification::new(&verged_pair());
        let (a, b) = ([-0.03, 0.01, 0.90], [0.03, 0.019, 0.93]);
        let (left, right) = images_of(&rect, a, b);
        let wrong = |p: [f64; 3]| in_cam(&rect, [p[0], p[1], p[2] + 0.05]);
        let (wa, wb) = (wrong(a), wrong(b));
        let completed = vec![Line3 {
            a: wa.into(),
            b: wb.into(),
            sigma_a: 0.001,
            sigma_b: 0.001,
            disparity_start: 200.0,
            disparity_end: 195.0,
            line2: 0,
            matches: 0,
            depths: Depths::Corners,
            inliers: Vec::new(),
        }];
        let lines3d = Found::of(&[left], &[right]).matched(&rect, &SEARCH, completed);
        assert_eq!(lines3d.len(), 1);
        assert_eq!(lines3d[0].depths, Depths::WholeLine);
        let off = distance_to_segment(&lines3d[0].start(), &in_cam(&rect, a), &in_cam(&rect, b));
        assert!(off < 1e-3, "{:.2} mm", off * 1e3);
    }
}
