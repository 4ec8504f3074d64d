//! Verification against accidental matches in the image: a located model's wireframe, projected
//! into the left image where its pose turns its faces to the camera, must run along edgels that
//! Canny found there (whether or not stereo recovered them). A pose that only happens to line up
//! a few 3D lines of other objects finds little such evidence.

use crate::canny::EdgeMap;
use crate::matcher::MatcherModel;
use mesh::PinholeCamera;
use nalgebra::{Isometry3, Vector2};

/// What the image offers to verify against: the left camera and its edgels.
pub struct ImageEvidence<'a> {
    pub cam: &'a PinholeCamera,
    pub edges: &'a EdgeMap,
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
    let (mut seen, mut all) = (0.0, 0.0);
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
        let dir = (b - a) / len;
        let steps = (len / STEP_PX) as usize;
        for k in 1..steps {
            let q = a + (b - a) * (k as f64 / steps as f64);
            all += STEP_PX;
            if edgel_along(ev.edges, q.x, q.y, dir) {
                seen += STEP_PX;
            }
        }
    }
    if all > 0.0 { seen / all } else { 0.0 }
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
