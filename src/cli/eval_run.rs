//! Evaluation of end-to-end runs. A [`Judge`] watches a run on a server started in this process,
//! reading the simulation's truth in-process ([`Server::truth`]; the socket does not serve it),
//! and judges it after the fact (what was on the table,
//! what each pick went for, what ended in the bin, how far the calibration was from the true
//! camera); `marvin eval run` ([`super::eval_run_batch`]) sums seeded runs.

use super::session::Watcher;
use marvin::engine::calibrate::Calibration;
use marvin::engine::recording::Recording;
use marvin::protocol::TruthReply;
use marvin::server::Server;
use nalgebra::Isometry3;
use serde_json::{Value, json};
use vision::matcher::Located;

/// One pick as evaluation judged it.
#[derive(Debug, Clone)]
pub struct JudgedPick {
    pub cycle: usize,
    pub model: String,
    pub support_fraction: f64,
    pub image_support: f64,
    /// The nearest object of the model chosen: its id, and how far from vision's pose (mm) and
    /// turned from it (degrees, under the model's symmetries).
    pub nearest: Option<(u32, f64, f64)>,
    /// The nearest object of any model: its id, model and how far, mm (what a wrong pick went for).
    pub nearest_any: Option<(u32, String, f64)>,
}

impl JudgedPick {
    /// The object the pick went for: the nearest of its model, if within [`TARGET_THERE_M`] and
    /// [`TARGET_TURN_DEG`] of vision's pose.
    pub fn target(&self) -> Option<u32> {
        self.nearest.filter(|(_, mm, deg)| *mm < TARGET_THERE_M * 1e3 && *deg < TARGET_TURN_DEG).map(|(id, ..)| id)
    }
}

/// What evaluation learns from the simulation after the fact (a local server only).
#[derive(Debug, Clone, Default)]
pub struct RunTruth {
    /// Objects on the table (not in a bin) at the start, and in a bin at the end.
    pub on_table_at_start: usize,
    pub in_bin_at_end: usize,
    /// Every pick tried, in order.
    pub picks: Vec<JudgedPick>,
    /// Why the scene had not settled when the cell started, if it had not.
    pub unsettled: Option<String>,
}

impl RunTruth {
    /// Picks at a pose where no object of the model chosen lay, as it lay.
    pub fn wrong_picks(&self) -> impl Iterator<Item = &JudgedPick> {
        self.picks.iter().filter(|p| p.target().is_none())
    }

    /// For each pick tried, whether it was a first attempt: the first at its object, or a wrong
    /// pick (each a try of its own, and a failed one).
    pub fn first_attempts(&self) -> Vec<bool> {
        let mut seen = std::collections::BTreeSet::new();
        self.picks.iter().map(|p| p.target().is_none_or(|id| seen.insert(id))).collect()
    }
}

/// A pick is at an object of the model chosen when one lies this near vision's pose, metres,
/// and turned from it by less than [`TARGET_TURN_DEG`]. Twice the matcher's "located" limits
/// (`marvin::eval::CORRECT_POS_M`, `CORRECT_ROT_DEG`): within these a grasp still lands on the
/// part's faces; a reading turned further is of another pose, however near its centre.
const TARGET_THERE_M: f64 = 0.02;
const TARGET_TURN_DEG: f64 = 10.0;

/// The nearest true object of `model` to vision's pose of it: its id, how far (mm) and how
/// turned (degrees, under the model's `symmetries`).
fn nearest_true(
    truth: &TruthReply,
    model: &str,
    cam_from_model: &Isometry3<f64>,
    symmetries: &[Isometry3<f64>],
) -> Option<(u32, f64, f64)> {
    let world_from_cam = truth.world_from_cam.to_isometry("world_from_cam").ok()?;
    let seen = world_from_cam * cam_from_model;
    truth
        .objects
        .iter()
        .filter(|o| o.model == model)
        .filter_map(|o| Some((o.id, o.world_from_model.to_isometry("world_from_model").ok()?)))
        .map(|(id, w)| {
            let (m, rad) = marvin::eval::pose_error(&seen, &w, symmetries);
            (id, m * 1e3, rad.to_degrees())
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The nearest true object (of `model`, or of any model) to vision's pose: id, model, mm.
fn nearest_object(
    truth: &TruthReply,
    model: Option<&str>,
    cam_from_model: &Isometry3<f64>,
) -> Option<(u32, String, f64)> {
    let world_from_cam = truth.world_from_cam.to_isometry("world_from_cam").ok()?;
    let p = world_from_cam * cam_from_model;
    truth
        .objects
        .iter()
        .filter(|o| model.is_none_or(|m| o.model == m))
        .filter_map(|o| Some((o, o.world_from_model.to_isometry("world_from_model").ok()?)))
        .map(|(o, w)| (o.id, o.model.clone(), (w.translation.vector - p.translation.vector).norm() * 1e3))
        .min_by(|a, b| a.2.total_cmp(&b.2))
}

/// How far a camera pose is from the true one: mm and degrees.
pub fn calibration_error(server: &Server, cam_from_base: &Isometry3<f64>) -> anyhow::Result<(f64, f64)> {
    let t = server.truth()?.cam_from_base.to_isometry("cam_from_base")?;
    Ok((
        (cam_from_base.translation.vector - t.translation.vector).norm() * 1e3,
        cam_from_base.rotation.angle_to(&t.rotation).to_degrees(),
    ))
}

/// Watches a run on a local server (and does nothing on a remote one, whose truth is not ours).
pub struct Judge<'a> {
    library: &'a mesh::Library,
    server: Option<&'a Server>,
    verdict: Verdict,
}

/// What a [`Judge`] found, kept once its server has stopped.
#[derive(Debug, Clone, Default)]
pub struct Verdict {
    pub truth: Option<RunTruth>,
    /// The run's own calibration against the true camera, mm and degrees.
    pub calibration_error: Option<(f64, f64)>,
}

impl<'a> Judge<'a> {
    /// A judge for a run on `server` (if it was started here), of objects from `library`.
    pub fn new(server: Option<&'a Server>, library: &'a mesh::Library) -> Judge<'a> {
        let verdict = Verdict { truth: server.map(|_| RunTruth::default()), calibration_error: None };
        Judge { library, server, verdict }
    }

    /// What it found; the server may stop now.
    pub fn verdict(self) -> Verdict {
        self.verdict
    }
}

impl Verdict {
    /// The judgement in `marvin run --json`'s document.
    pub fn add_to(&self, doc: &mut Value) {
        if let Some(t) = &self.truth {
            doc["truth"] = json!({
                "on_table_at_start": t.on_table_at_start,
                "in_bin_at_end": t.in_bin_at_end,
                "wrong_model_picks": t.wrong_picks().count(),
            });
        }
        if let Some((mm, deg)) = self.calibration_error {
            doc["calibration_error"] = json!({ "translation_mm": mm, "rotation_deg": deg });
        }
    }

    /// The judgement as lines for `marvin run`'s summary.
    pub fn summary(&self) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(t) = &self.truth {
            lines.push(format!(
                "against the simulation's truth: {} of {} objects cleared into the bin; {} picks at nothing of the model chosen",
                t.in_bin_at_end,
                t.on_table_at_start,
                t.wrong_picks().count()
            ));
        }
        if let Some((mm, deg)) = self.calibration_error {
            lines.push(format!("calibration: {mm:.2} mm, {deg:.3} deg from the true camera pose"));
        }
        lines
    }
}

impl Watcher for Judge<'_> {
    fn started(
        &mut self,
        cam_from_base: &Isometry3<f64>,
        calibration: Option<&Calibration>,
        recording: Option<&mut Recording>,
    ) -> anyhow::Result<()> {
        let (Some(t), Some(server)) = (self.verdict.truth.as_mut(), self.server) else { return Ok(()) };
        let start = server.truth()?;
        t.on_table_at_start = start.objects.iter().filter(|o| !o.in_bin).count();
        t.unsettled = start.unsettled;
        if calibration.is_some() {
            self.verdict.calibration_error = Some(calibration_error(server, cam_from_base)?);
            if let Some(r) = recording {
                r.true_camera(&start.cam_from_base.to_isometry("cam_from_base")?)?;
            }
        }
        Ok(())
    }

    fn before_pick(&mut self, cycle: usize, chosen: &Located) -> anyhow::Result<()> {
        let (Some(t), Some(server)) = (self.verdict.truth.as_mut(), self.server) else { return Ok(()) };
        let now = server.truth()?;
        t.picks.push(JudgedPick {
            cycle,
            model: chosen.model.clone(),
            support_fraction: chosen.support_fraction,
            image_support: chosen.image_support,
            nearest: self
                .library
                .get(&chosen.model)
                .and_then(|m| nearest_true(&now, &chosen.model, &chosen.cam_from_model, &marvin::eval::symmetries(m))),
            nearest_any: nearest_object(&now, None, &chosen.cam_from_model),
        });
        Ok(())
    }

    fn finished(&mut self, recording: Option<&mut Recording>) -> anyhow::Result<()> {
        let (Some(t), Some(server)) = (self.verdict.truth.as_mut(), self.server) else { return Ok(()) };
        let end = server.truth()?;
        t.in_bin_at_end = end.objects.iter().filter(|o| o.in_bin).count();
        if let Some(r) = recording {
            r.truth(&end, self.library)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::{JudgedPick, RunTruth};

    #[test]
    fn a_first_attempt_is_the_first_pick_at_an_object_or_a_wrong_pick() {
        let pick = |nearest: Option<(u32, f64, f64)>| JudgedPick {
            cycle: 0,
            model: "m".into(),
            support_fraction: 0.5,
            image_support: 0.5,
            nearest,
            nearest_any: None,
        };
        let picks = vec![
            pick(Some((3, 1.0, 0.5))),
            pick(None),
            pick(Some((3, 2.0, 1.0))),
            pick(Some((5, 0.5, 0.2))),
            pick(Some((5, 25.0, 0.2))),
        ];
        let t = RunTruth { picks, ..RunTruth::default() };
        // Wrong picks (no object of the model there) count as first attempts: every first pick
        // is in the rate's denominator.
        assert_eq!(t.first_attempts(), [true, true, false, true, true]);
        assert_eq!(t.wrong_picks().count(), 2);
    }

    /// A pick near an object of the model chosen but turned from it (beyond its symmetries) went
    /// for another pose: it is a wrong pick, judged by rotation as well as position.
    #[test]
    fn a_pick_turned_from_the_part_is_a_wrong_pick() {
        let pick = |mm: f64, deg: f64| JudgedPick {
            cycle: 0,
            model: "m".into(),
            support_fraction: 0.5,
            image_support: 0.5,
            nearest: Some((7, mm, deg)),
            nearest_any: None,
        };
        assert_eq!(pick(3.0, 2.0).target(), Some(7));
        assert_eq!(pick(3.0, 35.0).target(), None, "near, but turned 35 deg");
        assert_eq!(pick(30.0, 2.0).target(), None, "turned right, but 30 mm off");
    }

    /// The symmetries enter the turn: a block read half a turn about its long axis is the same
    /// pose; a quarter turn of a part with no such symmetry is not.
    #[test]
    fn the_turn_of_a_pick_is_measured_under_the_models_symmetries() {
        use marvin::protocol::{TruthObject, TruthReply, WirePose};
        use nalgebra::{Isometry3, UnitQuaternion, Vector3};
        let library = mesh::Library::load_default().unwrap();
        let world_from_model = Isometry3::translation(0.3, 0.1, 0.02);
        let truth = |model: &str| TruthReply {
            objects: vec![TruthObject {
                id: 1,
                model: model.into(),
                world_from_model: WirePose::new(None, &world_from_model),
                in_bin: false,
            }],
            tool_in_gripper: None,
            world_from_base: WirePose::new(None, &Isometry3::identity()),
            world_from_cam: WirePose::new(None, &Isometry3::identity()),
            cam_from_base: WirePose::new(None, &Isometry3::identity()),
            unsettled: None,
        };
        let turned = |model: &str, axis: Vector3<f64>, angle: f64| {
            let m = library.get(model).unwrap();
            let c = m.mass.centre_of_mass.coords;
            let about_centre = Isometry3::translation(c.x, c.y, c.z)
                * UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle)
                * Isometry3::translation(-c.x, -c.y, -c.z);
            let seen = world_from_model * about_centre;
            super::nearest_true(&truth(model), model, &seen, &marvin::eval::symmetries(m)).unwrap()
        };
        let sym = marvin::eval::symmetries(library.get("block").unwrap());
        assert!(sym.len() > 1, "a block maps onto itself by half turns");
        let (_, mm, deg) = turned("block", Vector3::z(), std::f64::consts::PI);
        assert!(mm < 1.0 && deg < 1.0, "a half turn of a block about z is the block: {mm} mm, {deg} deg");
        let (_, _, deg) = turned("block", Vector3::z(), std::f64::consts::FRAC_PI_2);
        assert!(deg > 80.0, "a quarter turn of a block about z is not: {deg} deg");
    }
}
