//! Which of a reading's edges the light lets the image show. An edge shows as edgels only where
//! the surfaces either side of it differ in grey: under a light from the side, a part's faces
//! turned from it show the ambient term alone, about the table's grey, and their edges against
//! the table and each other are all but gone (`side_light.toml`: 43-57 grey levels against the
//! table's 50, where Canny needs a step of 5-6). A part standing there shows its lit top and
//! little else, and is judged on its whole outline as if the light were behind the cameras.
//!
//! Nothing here is given: the light is the one the reports' faces agree on
//! ([`super::light::Light::fit_readings`]), a part's faces are taken at the scene's middling
//! brightness (its material is not known), and the table's grey is read beside the reports'
//! edges that rest on it, on the side away from the part. The image
//! look judges its starts again on the edges the light lets show once the light is known
//! ([`super::merge`]): on the tuning seeds (`marvin eval locate`, `widgets.toml` 1-500,
//! `dense.toml` and `side_light.toml` 1-200) located 98.50 / 93.21 / 95.76% -> 98.53 / 93.53 /
//! 97.55%, the same 5 / 14 / 2 false reports. [`DIM_STEP`] was set once from Canny's
//! thresholds, not tuned.

use super::light::{Light, median};
use super::model::{Located, MatcherModel, Table};
use super::shading::END_MARGIN;
use super::verify::ImageEvidence;
use nalgebra::{Isometry3, Point3, Vector3};

/// An edge whose two sides the light makes differ by less than this (grey levels) is not
/// expected to show. Canny's hysteresis needs a smoothed gradient of 2-2.5 levels a pixel
/// (`CannyParams::default`), a step of 5-6 levels; this leaves room for the light's fit.
pub const DIM_STEP: f64 = 8.0;
/// A report's edge rests on the table when both its ends lie this near the top (metres).
const ON_TABLE_M: f64 = 0.0015;
/// The table's grey is read from no fewer samples than this.
const MIN_TABLE_SAMPLES: usize = 12;
/// ...and no more than this (a median of so many is steady; each costs an edgel search).
const MAX_TABLE_SAMPLES: usize = 48;
/// Samples beside an edge are this far apart (pixels), the edge's ends left out.
const STEP_PX: f64 = 3.0;

/// What the image can show of a part: the scene's light and the table's grey.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shown {
    pub light: Light,
    /// The table's grey level, as the image shows it beside the parts resting on it.
    pub table_grey: f64,
}

impl Shown {
    /// The light with the table's grey read beside the edges of `kept` that rest on the
    /// `table` (outside the part); `None` where too few edgels show it.
    pub fn measure(
        light: Light,
        models: &[MatcherModel],
        kept: &[Located],
        ev: &ImageEvidence,
        table: &Table,
    ) -> Option<Shown> {
        let mut greys = Vec::new();
        for l in kept {
            let Some(model) = models.iter().find(|m| m.name == l.model) else { continue };
            let room = MAX_TABLE_SAMPLES.saturating_sub(greys.len());
            greys.extend(table_greys_beside(model, &l.cam_from_model, ev, table).take(room));
        }
        (greys.len() >= MIN_TABLE_SAMPLES).then(|| Shown { light, table_grey: median(&mut greys) })
    }

    /// The grey a face with outward normal `n` (`cam` frame) shows, of a part of the scene's
    /// middling brightness.
    fn grey(&self, n: &Vector3<f64>) -> f64 {
        self.light.predict(n)
    }

    /// Per line of `model` at `pose`, whether the light leaves its two sides (its faces turned
    /// to the camera, or the face and what lies beyond it, taken for the table) within
    /// [`DIM_STEP`] of each other: an edge the image is not expected to show. Markings and
    /// lines with no face turned to the camera are not dim.
    pub fn dim_lines(&self, model: &MatcherModel, pose: &Isometry3<f64>) -> Vec<bool> {
        let eye = super::model::eye_of(pose);
        (0..model.lines.len()).map(|k| self.is_dim(model, pose, &eye, k)).collect()
    }

    /// Whether line `k` of `model` at `pose` (the camera at `eye`, model frame) is dim, as
    /// [`Shown::dim_lines`] has it.
    fn is_dim(&self, model: &MatcherModel, pose: &Isometry3<f64>, eye: &Point3<f64>, k: usize) -> bool {
        if k >= model.first_marking {
            return false;
        }
        let mid = nalgebra::center(&model.lines[k].a, &model.lines[k].b);
        let mut facing = model.face_sides[k]
            .iter()
            .filter(|(n, _, _)| n.dot(&(eye - mid)) > 0.0)
            .map(|(n, _, _)| self.grey(&(pose.rotation * n)));
        match (facing.next(), facing.next(), facing.next()) {
            (Some(a), Some(b), None) => (a - b).abs() < DIM_STEP,
            (Some(a), None, None) => (a - self.table_grey).abs() < DIM_STEP,
            _ => false,
        }
    }
}

/// The grey levels the image shows beside `model`'s edges that rest on the `table` at `pose`,
/// on the side away from the part (where its one face turned to the camera is not), read off
/// the edgels running along them.
fn table_greys_beside<'a>(
    model: &'a MatcherModel,
    pose: &'a Isometry3<f64>,
    ev: &'a ImageEvidence,
    table: &'a Table,
) -> impl Iterator<Item = f64> + 'a {
    let eye = super::model::eye_of(pose);
    (0..model.first_marking).flat_map(move |k| {
        let line = &model.lines[k];
        let (a3, b3) = (pose * line.a, pose * line.b);
        let resting = table.height_of(&a3).abs() < ON_TABLE_M && table.height_of(&b3).abs() < ON_TABLE_M;
        let facing: Vec<_> = model.face_sides[k].iter().filter(|(n, _, _)| n.dot(&(eye - line.a)) > 0.0).collect();
        let ends = (ev.cam.project_cam(&a3), ev.cam.project_cam(&b3));
        let sampled = match (resting, &facing[..], ends) {
            (true, [(_, side, _)], (Some(a), Some(b))) => {
                let inside = ev.cam.project_cam(&(nalgebra::center(&a3, &b3) + pose.rotation * side * 0.005));
                inside.map(|inside| (a, b, nalgebra::center(&a, &b) - inside))
            }
            _ => None,
        };
        sampled.into_iter().flat_map(move |(a, b, away)| {
            let len = (b - a).norm();
            let dir = (b - a) / len.max(1e-9);
            let steps = (len / STEP_PX) as usize;
            (1..steps.max(1)).filter_map(move |s| {
                let f = s as f64 / steps as f64;
                if !(END_MARGIN..=1.0 - END_MARGIN).contains(&f) {
                    return None;
                }
                super::shading::grey_beside(ev, a + (b - a) * f, dir, away)
            })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::canny::{CannyParams, EdgeMap, canny};
    use crate::matcher::fixtures::{model, render, verged_pair};
    use nalgebra::{Translation3, UnitQuaternion};

    /// A block lying flat on the table (the world's z = 0) before the left camera of the
    /// fixtures' pair, with the table in that camera's frame.
    fn block_on_table() -> (MatcherModel, Isometry3<f64>, mesh::PinholeCamera, Table) {
        let block = model("block");
        let cam = verged_pair().0;
        let lowest = block.corners.iter().map(|c| c.z).fold(f64::MAX, f64::min);
        let world_from_model = Isometry3::from_parts(
            Translation3::new(0.02, -0.03, -lowest),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
        );
        let pose = cam.cam_from_world() * world_from_model;
        let table = Table::from_cam_from_table(&cam.cam_from_world());
        (block, pose, cam, table)
    }

    /// A light from `towards` (world frame) with the given ambient and diffuse terms (grey
    /// levels per unit albedo), in the camera's frame.
    fn light(cam: &mesh::PinholeCamera, towards: Vector3<f64>, ambient: f64, diffuse: f64) -> Light {
        Light { ambient, towards_light: cam.cam_from_world().rotation * towards.normalize() * diffuse }
    }

    fn located(model: &MatcherModel, pose: Isometry3<f64>) -> Located {
        crate::matcher::fixtures::report(model, pose)
    }

    /// Drawn on a table of 90 grey levels under a light from the cameras' side, the block's
    /// edges on the table read the table's grey beside them, outside the block; with no edgels
    /// there is nothing to read.
    #[test]
    fn the_tables_grey_is_read_beside_the_edges_a_part_rests_on() {
        let (block, pose, cam, table) = block_on_table();
        let lit = light(&cam, Vector3::new(-0.2, -1.0, 1.0), 0.2 * 255.0, 0.8 * 255.0);
        let edges = canny(&render(&cam, &[(&block, pose)], &|n| lit.predict(n), 90), &CannyParams::default());
        let ev = ImageEvidence::new(&cam, &edges, Vec::new());
        let shown = Shown::measure(lit, std::slice::from_ref(&block), &[located(&block, pose)], &ev, &table);
        let grey = shown.expect("the table's grey").table_grey;
        assert!((grey - 90.0).abs() < 2.0, "read {grey:.1}");
        let no_edgels = EdgeMap::new(512, 512);
        let bare = ImageEvidence::new(&cam, &no_edgels, Vec::new());
        assert!(Shown::measure(lit, std::slice::from_ref(&block), &[located(&block, pose)], &bare, &table).is_none());
    }

    /// Lit from the cameras' side, every edge of the block the camera sees shows; lit from
    /// behind, its camera-facing sides are left the ambient grey, the table's: the edges
    /// between them and along the table are dim, its top's are not.
    #[test]
    fn the_edges_between_faces_of_one_grey_are_dim() {
        let (block, pose, cam, _) = block_on_table();
        let facing: Vec<usize> = (0..block.lines.len()).filter(|k| block.faces_camera(*k, &pose)).collect();
        // The light as the image shows it on the block: its material's share of the drawing light.
        let albedo = crate::matcher::fixtures::albedo("block");
        let seen = |l: Light| Light { ambient: albedo * l.ambient, towards_light: albedo * l.towards_light };
        let front = seen(light(&cam, Vector3::new(-0.2, -1.0, 1.0), 0.2 * 255.0, 0.8 * 255.0));
        let shown = Shown { light: front, table_grey: 40.0 };
        assert!(facing.iter().all(|k| !shown.dim_lines(&block, &pose)[*k]));
        let behind = seen(light(&cam, Vector3::new(0.2, 1.0, 1.0), 0.2 * 255.0, 0.8 * 255.0));
        let shown = Shown { light: behind, table_grey: behind.ambient };
        let dim = shown.dim_lines(&block, &pose);
        let up = Vector3::from(Table::from_cam_from_table(&cam.cam_from_world()).up);
        for k in facing {
            let on_top = block.faces[k].iter().any(|n| (pose.rotation * n).dot(&up) > 0.99);
            assert_eq!(dim[k], !on_top, "edge {k} (on the top: {on_top})");
        }
    }
}
