//! Depth order: a report whose solid would stand in front of edges stereo found behind it.
//!
//! A reading puts a solid in the scene, and a solid hides what lies behind it. Where stereo
//! matched edgels inside the reading's outline at depths well beyond its front surface, the
//! camera saw through the place the reading fills: the part is not there. The merge
//! ([`super::merge::resolve`]) refuses such a reading before it is kept.
//!
//! On tuning seeds (`marvin eval locate`, realistic `widgets.toml` 1-300 and `dense.toml` 1-60
//! through tuning seed 1's calibrations, ideal `widgets.toml` 1-100 and `dense.toml` 1-60) one
//! right report of about 5,000 had any matched edgel behind it (12 of 84 inside its outline,
//! along one line, 5-7 px of disparity behind a T-piece); one false report, a block read on a
//! widget lying on its side, had all 28. Most false reports lie where a real surface does.

use super::model::MatcherModel;
use super::occlusion::Solid;
use super::verify::ImageEvidence;
use nalgebra::{Isometry3, Vector3};

/// Edgels within this distance (pixels) of the reading's outline are not counted: a pose a
/// little off puts the edges beside a part inside its outline.
const INSET_PX: f64 = 3.0;
/// The four offsets (pixels) whose lines of sight must all enter the reading's solid.
const INSET: [(f64, f64); 4] = [(INSET_PX, 0.0), (-INSET_PX, 0.0), (0.0, INSET_PX), (0.0, -INSET_PX)];
/// An edgel lies behind the reading's surface if it is further than this many pixels of
/// disparity beyond it.
const BEHIND_PX: f64 = 3.0;

/// What stereo's depths say inside a reading's outline.
#[derive(Debug, Clone, Copy, Default)]
pub struct SeenThrough {
    /// Matched edgels inside the outline (by at least [`INSET_PX`]).
    pub inside: usize,
    /// Of those, the ones lying behind its front surface.
    pub behind: usize,
}

impl SeenThrough {
    /// Whether the camera saw through the reading: most of the matched edgels inside its
    /// outline, and at least [`MIN_BEHIND`], lie behind it.
    pub fn refutes(&self) -> bool {
        self.behind >= MIN_BEHIND && 2 * self.behind > self.inside
    }

    /// Whether the camera saw through some of the reading's place: at least [`MIN_BEHIND`]
    /// matched edgels lie behind it, whatever lies in front of the rest.
    pub fn in_part(&self) -> bool {
        self.behind >= MIN_BEHIND
    }
}

/// A reading is refuted by no fewer edgels behind it than this (a stretch of edge, not a
/// stray match).
const MIN_BEHIND: usize = 10;

/// The matched edgels inside `model`'s outline at `pose` and how many of them lie behind it
/// (`None` without stereo's depths).
pub fn seen_through(model: &MatcherModel, pose: &Isometry3<f64>, ev: &ImageEvidence) -> Option<SeenThrough> {
    let depths = ev.depths.as_ref()?;
    let solid = Solid::new(model, pose);
    let (centre, radius) = model.bounding_sphere();
    let c = pose * centre;
    let at = ev.cam.project_cam(&c)?;
    let reach_px = ev.cam.fx * radius / (c.z - radius).max(1e-3) + 2.0;
    let mut out = SeenThrough::default();
    for (i, e) in ev.edges.edgels.iter().enumerate() {
        let (x, y) = (e.x as f64, e.y as f64);
        if (x - at.x).abs() > reach_px || (y - at.y).abs() > reach_px {
            continue;
        }
        let Some((z, per_px)) = depths.of_edgel(i) else { continue };
        let ray = |dx: f64, dy: f64| -> Vector3<f64> { ev.cam.ray_cam(x + dx, y + dy) };
        let Some(front) = solid.entry(&ray(0.0, 0.0)) else { continue };
        if INSET.iter().any(|&(dx, dy)| solid.entry(&ray(dx, dy)).is_none()) {
            continue;
        }
        out.inside += 1;
        if z > front + BEHIND_PX * per_px {
            out.behind += 1;
        }
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::{camera_at, model};
    use crate::matcher::verify::drawn;
    use nalgebra::{Point3, Translation3, UnitQuaternion};

    /// A block on the table as the test camera sees it (`cam` frame), moved `towards` the
    /// camera by that share of its distance.
    fn block_at(cam: &mesh::PinholeCamera, towards: f64) -> Isometry3<f64> {
        let world_from_block = Isometry3::from_parts(
            Translation3::new(0.01, -0.02, 0.015),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.4),
        );
        let pose = cam.cam_from_world() * world_from_block;
        Isometry3::from_parts((pose.translation.vector * (1.0 - towards)).into(), pose.rotation)
    }

    /// A block with stereo's depths along its own edges: nothing lies behind it.
    #[test]
    fn a_block_where_it_lies_is_not_seen_through() {
        let cam = camera_at(Point3::new(-0.1, -0.6894, 0.5785));
        let (block, pose) = (model("block"), block_at(&cam, 0.0));
        let (edges, lines) = drawn::model_edges(&block, &pose, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines).with_depths(drawn::model_depths(&block, &pose, &cam, &edges));
        let s = seen_through(&block, &pose, &ev).unwrap();
        assert_eq!(s.behind, 0, "{s:?}");
        assert!(!s.refutes());
    }

    /// A block read 8 cm nearer the camera than the one stereo saw: the camera saw the far
    /// block's edges through the place the reading fills, and the reading is refuted. The
    /// other way round the near block hides nothing stereo found: edges in front of a reading
    /// are an object hiding it, not evidence against it.
    #[test]
    fn a_reading_in_front_of_edges_stereo_found_behind_it_is_refuted() {
        let cam = camera_at(Point3::new(-0.1, -0.6894, 0.5785));
        let (block, far, near) = (model("block"), block_at(&cam, 0.0), block_at(&cam, 0.09));
        let (edges, lines) = drawn::model_edges(&block, &far, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines).with_depths(drawn::model_depths(&block, &far, &cam, &edges));
        let s = seen_through(&block, &near, &ev).unwrap();
        assert!(s.inside >= 10 && s.refutes() && s.in_part(), "{s:?}");
        let (edges, lines) = drawn::model_edges(&block, &near, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines).with_depths(drawn::model_depths(&block, &near, &cam, &edges));
        let s = seen_through(&block, &far, &ev).unwrap();
        assert_eq!(s.behind, 0, "{s:?}");
        assert!(!s.in_part());
    }
}
