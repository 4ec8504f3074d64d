//! A part read turned over, told apart by stereo's depths along its wireframe, or by the image.
//!
//! A flat part turned over (an L-bracket face down, a wedge turned end for end) lies in the
//! same box as the part itself and along many of the same image edges; where few of its edges
//! give 3D lines, the turned reading matches those few as well and may run along more edgels,
//! the true one being half hidden. But the turned reading puts some of the edges it shares in
//! the image at other depths, and PMF's matched edgels there say so even where no 3D line was
//! fitted ([`super::depths`]). So a report on little 3D evidence whose wireframe the edgels'
//! depths contradict is looked at again turned over (each half turn of its box, refitted on
//! the 3D lines and the image, as the shading check does), and the turn takes its place where
//! it keeps the 3D evidence, the edgels' agreeing depths and most of the image, and is
//! contradicted half as much or less.
//!
//! Chosen on tuning seeds (`marvin eval locate`, `widgets.toml` 1-500, `dense.toml` and
//! `side_light.toml` 1-200): the turn put right 6, 1 and 2 reports turned over and undid
//! none that was right. Asking 90% of the agreeing depths instead of 95% put right one more
//! (widgets) and turned two correct widgets over (one widgets, one dense).
//!
//! Where the depths say nothing, a turn that keeps the 3D evidence and runs along clearly more
//! of the image takes the report's place ([`turn_by_image`]).

use super::model::{Located, MatchParams, MatcherModel, Seg};
use super::occlusion::Solid;
use super::shading::TurnedCandidates;
use super::turns::{half_turns, is_symmetry};
use super::verify::{ImageEvidence, depth_agreement, image_support, image_support_at_least, image_support_unhidden};
use nalgebra::Isometry3;

/// Reports whose wireframe edgels' depths contradict for less than this length (pixels) are
/// not looked at again.
const MIN_CONTRADICTED_PX: f64 = 16.0;
/// A turn takes a report's place only if it keeps this share of its matched 3D length...
const KEEP_SUPPORT: f64 = 0.9;
/// ...this share of its wireframe where edgels' depths agree...
const KEEP_AGREEING: f64 = 0.95;
/// ...its share of wireframe along edgels (over the part in view) less no more than this...
const IMAGE_LOSS: f64 = 0.2;
/// ...and is contradicted by edgels' depths for no more than this share of the report's length.
const CONTRADICTED_RATIO: f64 = 0.5;

/// How the evidence judges one reading: the wireframe (pixels) where edgels' depths agree with
/// it and where they contradict it, and its share along edgels over the part in view.
struct Judged {
    agreeing: f64,
    contradicted: f64,
    image: f64,
}

/// Each report on little 3D evidence (less than `max_support` of its model's length matched)
/// replaced by itself turned over where the edgels' depths bear the turn out far better; the
/// reports' solids hide one another's edges.
pub(crate) fn turn_by_depth(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    (max_support, turns): (f64, &TurnedCandidates),
    kept: &mut [Located],
) {
    let model_of = |name: &str| models.iter().find(|m| m.name == name);
    let solids: Vec<Option<Solid>> =
        kept.iter().map(|l| model_of(&l.model).map(|m| Solid::new(m, &l.cam_from_model))).collect();
    // Each report judged on its own (against the others' solids where they stood), in parallel.
    use rayon::prelude::*;
    kept.par_iter_mut().enumerate().for_each(|(i, report)| {
        let Some(model) = model_of(&report.model) else { return };
        if report.support_fraction >= max_support {
            return;
        }
        let others: Vec<&Solid> =
            solids.iter().enumerate().filter(|(j, _)| *j != i).filter_map(|(_, s)| s.as_ref()).collect();
        if let Some(turned) = turned_over(model, (scene, p), (ev, turns), &others, report) {
            *report = turned;
        }
    });
}

/// `report` turned over, if the edgels' depths bear the turn out far better.
fn turned_over(
    model: &MatcherModel,
    (scene, p): (&[Seg], &MatchParams),
    (ev, turns): (&ImageEvidence, &TurnedCandidates),
    others: &[&Solid],
    report: &Located,
) -> Option<Located> {
    let now = judge(model, &report.cam_from_model, ev, others)?;
    if now.contradicted < MIN_CONTRADICTED_PX {
        return None;
    }
    use rayon::prelude::*;
    let (_, c) = half_turns(model)
        .into_par_iter()
        .filter_map(|turn| {
            let c = turns.refit(model, (scene, p), ev, report.cam_from_model * turn)?;
            let then = judge(model, &c.pose, ev, others)?;
            (c.score >= KEEP_SUPPORT * report.support
                && then.agreeing >= KEEP_AGREEING * now.agreeing
                && then.image >= now.image - IMAGE_LOSS
                && then.contradicted <= CONTRADICTED_RATIO * now.contradicted)
                .then_some((then.contradicted, c))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))?;
    Some(c.located(model, image_support(model, &c.pose, ev)))
}

/// `model` at `pose` judged with `others` (and its own bulk, if not convex) hiding what lies
/// behind them.
fn judge(model: &MatcherModel, pose: &Isometry3<f64>, ev: &ImageEvidence, others: &[&Solid]) -> Option<Judged> {
    let own = (!model.convex).then(|| Solid::new(model, pose));
    let hiding: Vec<&Solid> = others.iter().copied().chain(own.as_ref()).collect();
    let (agreeing, contradicted) = depth_agreement(model, pose, ev, &hiding)?;
    let (image, _) = image_support_unhidden(model, pose, ev, others);
    Some(Judged { agreeing, contradicted, image })
}

/// Each report replaced by the best of its half turns (refitted on the 3D lines and the image)
/// where that keeps [`IMAGE_TURN_KEEP`] of its matched 3D length and runs along edgels for
/// [`IMAGE_TURN_GAIN`] more of its wireframe. A part read turned over where only a few of its
/// lines gave 3D lines matches those as well as the part does; which way round it lies the
/// image often shows plainly, by edges one reading has and the other lacks (an L-bracket's
/// inner corner, a widget's step). The searches never verify the turn if its hypotheses rank
/// below the turned reading's many variants.
///
/// Every report is looked at, whatever its 3D evidence: a widget seen end on shares so many
/// lines with itself turned about its profile's long axis that the turned reading matched
/// 30% of its length or more (`widgets.toml` seed 1197, `dense.toml` seed 145, where the
/// turn, keeping all of that, ran along edgels for 0.13 more of its wireframe). Looking at
/// all of them, not only those under 30%, put those two right on the tuning seeds
/// (`widgets.toml` 1-1500, `dense.toml` and `side_light.toml` 1-200) and changed nothing else;
/// a turn is refitted only where it starts near the report along edgels
/// ([`IMAGE_TURN_START_SLACK`]).
pub(crate) fn turn_by_image(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    turns: &TurnedCandidates,
    kept: &mut [Located],
) {
    // Each report judged on its own, in parallel.
    use rayon::prelude::*;
    kept.par_iter_mut().for_each(|report| {
        let Some(model) = models.iter().find(|m| m.name == report.model) else { return };
        let now = image_support(model, &report.cam_from_model, ev);
        // Along edgels for more than this, no turn could gain enough.
        if now + IMAGE_TURN_GAIN > 1.0 {
            return;
        }
        let better = half_turns(model)
            .into_par_iter()
            // A symmetry of the part reads it as the report does.
            .filter(|turn| !is_symmetry(model, turn))
            // Refitting is most of the cost: a turn that starts far below the report along
            // edgels is not refitted.
            .map(|turn| report.cam_from_model * turn)
            .filter(|start| image_support_at_least(model, start, ev, now - IMAGE_TURN_START_SLACK).is_some())
            .filter_map(|start| turns.refit(model, (scene, p), ev, start))
            .filter(|c| c.score >= IMAGE_TURN_KEEP * report.support && c.image_support >= now + IMAGE_TURN_GAIN)
            .max_by(|a, b| a.image_support.total_cmp(&b.image_support));
        if let Some(c) = better {
            *report = c.located(model, c.image_support);
        }
    });
}

/// A turn replaces a report in [`turn_by_image`] if it runs along edgels for this much more of
/// its wireframe (a share of it)...
///
/// Chosen on tuning seeds (`marvin eval locate`, `widgets.toml` 1-500, `dense.toml` and
/// `side_light.toml` 1-200): the turns that put a report right gained 0.064-0.195; the two that
/// turned a right report over gained 0.021 and 0.022 (with 0.02 only two of the five right
/// turns were made, those keeping all the 3D length).
const IMAGE_TURN_GAIN: f64 = 0.05;
/// ...and keeps this share of its matched 3D length (one right turn kept 0.91).
const IMAGE_TURN_KEEP: f64 = 0.9;
/// A turn is refitted only if, turned where the report lies, it runs along edgels for no less
/// than the report's share less this. Over the tuning seeds (`widgets.toml` 1-1500, `dense.toml`
/// and `side_light.toml` 1-200) the 13 turns taken started at most 0.076 below the report and
/// ended 0.04-0.30 above it; most turns of a report on many 3D lines start far below it, and
/// refitting them all made `marvin bench vision`'s match 10% slower.
const IMAGE_TURN_START_SLACK: f64 = 0.1;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::{camera_at, model};
    use crate::matcher::verify::drawn;
    use nalgebra::{Point3, Translation3, UnitQuaternion};

    /// The wedge, the test camera, and the wedge's pose (`cam` frame) turned by these Euler
    /// angles (radians) on the table.
    fn wedge_seen(roll: f64, pitch: f64) -> (MatcherModel, mesh::PinholeCamera, Isometry3<f64>) {
        let cam = camera_at(Point3::new(-0.1, -0.6894, 0.5785));
        let world_from_model = Isometry3::from_parts(
            Translation3::new(0.01, -0.02, 0.0),
            UnitQuaternion::from_euler_angles(roll, pitch, 0.4),
        );
        let truth = cam.cam_from_world() * world_from_model;
        (model("wedge"), cam, truth)
    }

    /// A wedge on its side seen with its true depths; the image shows the edges of it turned
    /// over as well (as where other objects' edges lie there), so only the depths can tell.
    /// Read turned over, it is turned back.
    #[test]
    fn a_wedge_read_turned_over_is_turned_back_by_its_edgels_depths() {
        let (wedge, cam, truth) = wedge_seen(std::f64::consts::PI, 1.0);
        let turned_reading = truth * half_turns(&wedge)[1];
        let (mut edges, lines) = drawn::model_edges(&wedge, &truth, &cam);
        let (turned_edges, _) = drawn::model_edges(&wedge, &turned_reading, &cam);
        for (e, &pixel) in turned_edges.edgels.iter().zip(&turned_edges.pixel) {
            if edges.edgel_at(pixel as usize % 512, pixel as usize / 512).is_none() {
                edges.push(pixel as usize, *e);
            }
        }
        let ev = ImageEvidence::new(&cam, &edges, lines).with_depths(drawn::model_depths(&wedge, &truth, &cam, &edges));
        let p = MatchParams::default();
        let scene: Vec<Seg> = wedge
            .lines
            .iter()
            .enumerate()
            .filter(|(k, _)| wedge.faces_camera(*k, &truth))
            .map(|(_, l)| l.transformed(&truth))
            .collect();
        let report = Located {
            model: wedge.name.clone(),
            cam_from_model: turned_reading,
            support: crate::matcher::support::support(&wedge, &turned_reading, &scene, &vec![true; scene.len()], &p).0,
            support_fraction: 0.1,
            scene_lines: Vec::new(),
            image_support: image_support(&wedge, &turned_reading, &ev),
            grasps: Vec::new(),
        };
        let mut kept = vec![report];
        turn_by_depth(std::slice::from_ref(&wedge), (&scene, &p), &ev, (0.3, &TurnedCandidates::default()), &mut kept);
        let got = kept[0].cam_from_model;
        assert!((got.translation.vector - truth.translation.vector).norm() < 1e-3, "turned back to where it lies");
        assert!(got.rotation.angle_to(&truth.rotation) < 0.02, "and as it lies");
    }

    /// A report the edgels' depths bear out is left as it is.
    #[test]
    fn a_wedge_read_as_it_lies_is_left_alone() {
        let (wedge, cam, truth) = wedge_seen(0.0, 0.0);
        let (edges, lines) = drawn::model_edges(&wedge, &truth, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines).with_depths(drawn::model_depths(&wedge, &truth, &cam, &edges));
        let scene: Vec<Seg> = wedge.lines.iter().map(|l| l.transformed(&truth)).collect();
        let report = Located {
            model: wedge.name.clone(),
            cam_from_model: truth,
            support: 0.05,
            support_fraction: 0.1,
            scene_lines: Vec::new(),
            image_support: 1.0,
            grasps: Vec::new(),
        };
        let mut kept = vec![report];
        turn_by_depth(
            std::slice::from_ref(&wedge),
            (&scene, &MatchParams::default()),
            &ev,
            (0.3, &TurnedCandidates::default()),
            &mut kept,
        );
        assert_eq!(kept[0].cam_from_model, truth);
    }

    /// A report of `wedge` at `pose` on `scene`, its support counted there.
    fn report_at(wedge: &MatcherModel, pose: Isometry3<f64>, scene: &[Seg], ev: &ImageEvidence) -> Located {
        let p = MatchParams::default();
        let support = crate::matcher::support::support(wedge, &pose, scene, &vec![true; scene.len()], &p).0;
        Located {
            model: wedge.name.clone(),
            cam_from_model: pose,
            support,
            support_fraction: support / wedge.total_length,
            scene_lines: Vec::new(),
            image_support: image_support(wedge, &pose, ev),
            grasps: Vec::new(),
        }
    }

    /// A wedge on its side, its 3D lines those of the edges it shares with itself turned over,
    /// the image showing it as it lies (no depths): read turned over, the image turns it back,
    /// though the turned reading matched 41% of the wedge's length; read as it lies, it stays.
    #[test]
    fn a_wedge_read_turned_over_is_turned_back_where_the_image_shows_it_plainly() {
        let (wedge, cam, truth) = wedge_seen(std::f64::consts::PI, 1.0);
        let (edges, lines) = drawn::model_edges(&wedge, &truth, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines);
        let p = MatchParams::default();
        // The lines a reading turned over puts where the wedge has them; the turn sharing most.
        let shared_with = |turned: &Isometry3<f64>| -> Vec<Seg> {
            let same = |x: &Point3<f64>, y: &Point3<f64>| (x - y).norm() < 1e-6;
            let at_turned: Vec<Seg> = wedge.lines.iter().map(|m| m.transformed(turned)).collect();
            let shared = |t: &Seg| {
                at_turned
                    .iter()
                    .any(|m| (same(&m.a, &t.a) && same(&m.b, &t.b)) || (same(&m.a, &t.b) && same(&m.b, &t.a)))
            };
            wedge.lines.iter().map(|l| l.transformed(&truth)).filter(shared).collect()
        };
        let turned_reading =
            half_turns(&wedge).map(|turn| truth * turn).into_iter().max_by_key(|t| shared_with(t).len()).unwrap();
        let scene = shared_with(&turned_reading);
        assert!(scene.len() >= 3, "the readings share {} lines", scene.len());
        let turned = report_at(&wedge, turned_reading, &scene, &ev);
        // Well supported, as the readings of a part turned over that shares many lines can be.
        assert!(
            turned.support_fraction > 0.3,
            "the turned reading matches {:.2} of the wedge",
            turned.support_fraction
        );
        assert!(
            image_support(&wedge, &truth, &ev) > turned.image_support + IMAGE_TURN_GAIN,
            "the image shows the wedge as it lies better than turned over"
        );
        let mut kept = vec![turned];
        turn_by_image(std::slice::from_ref(&wedge), (&scene, &p), &ev, &TurnedCandidates::default(), &mut kept);
        // As it lies: its wireframe where the wedge's is (a symmetric pose will do).
        let got = kept[0].cam_from_model;
        let ends = |pose: &Isometry3<f64>| -> Vec<Point3<f64>> {
            wedge.lines.iter().flat_map(|l| [pose * l.a, pose * l.b]).collect()
        };
        let truth_ends = ends(&truth);
        let off = ends(&got)
            .iter()
            .map(|e| truth_ends.iter().map(|t| (e - t).norm()).fold(f64::MAX, f64::min))
            .fold(0.0, f64::max);
        assert!(off < 1e-3, "turned back to where it lies, as it lies: a corner {off} m off");
        let mut kept = vec![report_at(&wedge, truth, &scene, &ev)];
        turn_by_image(std::slice::from_ref(&wedge), (&scene, &p), &ev, &TurnedCandidates::default(), &mut kept);
        assert_eq!(kept[0].cam_from_model, truth, "read as it lies, it stays");
    }
}
