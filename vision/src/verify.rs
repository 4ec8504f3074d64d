//! Verification against accidental matches in the image: a located model's wireframe, projected
//! into the left image where its pose turns its faces to the camera, must run along edgels that
//! Canny found there (whether or not stereo recovered them). A pose that only happens to line up
//! a few 3D lines of other objects finds little such evidence.

use crate::canny::EdgeMap;
use crate::matcher::MatcherModel;
use mesh::PinholeCamera;
use nalgebra::{Isometry3, Vector2};

/// What the image offers to verify against: the left camera, its edgels, and the straight
/// image lines stereo did not lift to 3D (mostly edges near the rasters' direction).
pub struct ImageEvidence<'a> {
    pub cam: &'a PinholeCamera,
    pub edges: &'a EdgeMap,
    pub lines: Vec<ImageLine>,
}

/// A straight line of the left image, in pixels, with the plane through the camera centre that
/// holds it (unit normal, `cam` frame): a 3D edge seen as this line lies in that plane.
#[derive(Debug, Clone, Copy)]
pub struct ImageLine {
    pub a: nalgebra::Point2<f64>,
    pub b: nalgebra::Point2<f64>,
    pub normal: nalgebra::Vector3<f64>,
}

/// Image lines shorter than this (pixels) are not used.
const MIN_IMAGE_LINE_PX: f64 = 20.0;

impl<'a> ImageEvidence<'a> {
    /// The evidence of one front-end run on the left camera `cam`.
    pub fn of(cam: &'a PinholeCamera, fe: &'a crate::front_end::FrontEnd) -> ImageEvidence<'a> {
        let lifted: std::collections::HashSet<u32> = fe.lines3d.iter().map(|l| l.line2).collect();
        let lines = match &fe.rect {
            None => Vec::new(),
            Some(rect) => fe
                .lines2d
                .iter()
                .enumerate()
                .filter(|(i, l)| !lifted.contains(&(*i as u32)) && l.length() as f64 >= MIN_IMAGE_LINE_PX)
                .map(|(_, l)| {
                    let px = |p: [f32; 2]| {
                        let (x, y) = rect.from_rectified(crate::rectify::Side::Left, p[0] as f64, p[1] as f64);
                        nalgebra::Point2::new(x, y)
                    };
                    let (a, b) = (px(l.start), px(l.end));
                    let normal = cam.ray_cam(a.x, a.y).cross(&cam.ray_cam(b.x, b.y)).normalize();
                    ImageLine { a, b, normal }
                })
                .collect(),
        };
        ImageEvidence { cam, edges: &fe.left, lines }
    }
}

/// Image samples taken every this many pixels along a projected line.
const STEP_PX: f64 = 2.0;
/// An edgel within this distance (pixels)...
const NEAR_PX: f64 = 1.5;
/// ...whose edge runs within this angle (radians) of the projected line counts as evidence.
const ALONG_RAD: f64 = 0.35;

/// The fraction of the projected, camera-facing wireframe (by length in the image) that runs
/// along edgels.
pub fn image_support(model: &MatcherModel, pose: &Isometry3<f64>, ev: &ImageEvidence) -> f64 {
    image_support_at_least(model, pose, ev, 0.0).unwrap_or(0.0)
}

/// [`image_support`], given up (`None`) as soon as it cannot reach `min`: the samples are laid
/// out first, and the count stops when even all the samples left could not lift it to `min`.
pub fn image_support_at_least(
    model: &MatcherModel,
    pose: &Isometry3<f64>,
    ev: &ImageEvidence,
    min: f64,
) -> Option<f64> {
    let mut segments = Vec::new();
    let mut all = 0.0;
    for (line, faces) in model.lines.iter().zip(&model.faces) {
        let mid = pose * (line.a + (line.b - line.a) * 0.5);
        if !faces.is_empty() && !faces.iter().any(|n| (pose.rotation * n).dot(&-mid.coords) > 0.0) {
            continue;
        }
        let (Some(a), Some(b)) = (ev.cam.project_cam(&(pose * line.a)), ev.cam.project_cam(&(pose * line.b))) else {
            continue;
        };
        let len = (b - a).norm();
        if len < 2.0 * STEP_PX {
            continue;
        }
        let steps = (len / STEP_PX) as usize;
        all += STEP_PX * (steps - 1) as f64;
        segments.push((a, b, (b - a) / len, steps));
    }
    if all <= 0.0 {
        return (min <= 0.0).then_some(0.0);
    }
    let (mut seen, mut missed) = (0.0, 0.0);
    for (a, b, dir, steps) in segments {
        for k in 1..steps {
            let q = a + (b - a) * (k as f64 / steps as f64);
            if edgel_along(ev.edges, q.x, q.y, dir) {
                seen += STEP_PX;
            } else {
                missed += STEP_PX;
                if (all - missed) / all < min {
                    return None;
                }
            }
        }
    }
    Some(seen / all)
}

fn edgel_along(edges: &EdgeMap, x: f64, y: f64, dir: Vector2<f64>) -> bool {
    let (cx, cy) = (x.round() as i64, y.round() as i64);
    let r = NEAR_PX.ceil() as i64;
    for py in cy - r..=cy + r {
        for px in cx - r..=cx + r {
            if px < 0 || py < 0 || px >= edges.width as i64 || py >= edges.height as i64 {
                continue;
            }
            let Some(i) = edges.edgel_at(px as usize, py as usize) else { continue };
            let e = &edges.edgels[i as usize];
            let (dx, dy) = (e.x as f64 - x, e.y as f64 - y);
            // Distance across the line, and the edge's own direction (perpendicular to its gradient).
            let across = (dx * dir.y - dy * dir.x).abs();
            let (s, c) = (e.orientation as f64).sin_cos();
            let tangent = Vector2::new(-s, c);
            if across <= NEAR_PX && tangent.dot(&dir).abs() >= ALONG_RAD.cos() {
                return true;
            }
        }
    }
    false
}
