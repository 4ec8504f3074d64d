//! One model's virtual matcher: its characteristic views searched by subordinate matchers,
//! the best candidate verified and kept, then further instances from the same hypotheses
//! rescored on the lines still free.

use super::hypotheses::{ScenePairs, hypotheses, rescored, scene_pairs};
use super::model::{Located, MatchParams, MatcherModel, Seg};
use super::ranking::{Candidate, best_of, image_support_needed, in_image, refine_among};
use super::support::{FreeLines, model_lines_of};
use super::table::through_table;
use super::verify::{ImageEvidence, image_support_at_least};
use super::views::characteristic_views;
use nalgebra::Isometry3;

/// Finds the instances of `model` among `scene` lines (in the `cam` frame).
pub fn locate(model: &MatcherModel, scene: &[Seg], p: &MatchParams, image: Option<&ImageEvidence>) -> Vec<Located> {
    locate_from(model, scene, &scene_pairs(scene, p), p, image).found
}

/// What one model's search leaves: the instances found, and the last round's candidates that
/// had the 3D evidence but not the image evidence (parts of them may be hidden, see
/// [`locate_all`]), best supported first.
pub(crate) struct Search {
    pub(crate) found: Vec<Located>,
    pub(crate) doubtful: Vec<Candidate>,
    /// Hypotheses short of the first look's support that put the part flat on the table, for
    /// the table look ([`super::table_look`]).
    pub(crate) flat: Vec<(f64, Isometry3<f64>)>,
}

/// [`locate`], with the scene's seed pairs given (every model's matcher searches the same).
pub(crate) fn locate_from(
    model: &MatcherModel,
    scene: &[Seg],
    pairs: &ScenePairs,
    p: &MatchParams,
    image: Option<&ImageEvidence>,
) -> Search {
    // Tabled once per model; a search with another number of focus lines tables its own.
    let tabled = model.views.get_or_init(|| (p.focus_lines, characteristic_views(model, p)));
    let own;
    let views = if tabled.0 == p.focus_lines {
        &tabled.1
    } else {
        own = characteristic_views(model, p);
        &own
    };
    let mut free = vec![true; scene.len()];
    let mut found = Vec::new();
    let (mut seen, flat) = hypotheses(model, scene, pairs, views, p);
    let mut doubtful = Vec::new();
    for round in 0..p.max_instances {
        if round > 0 {
            seen = rescored(model, scene, &free, &seen, p);
        }
        // The best-supported hypotheses, each refined and checked against the image, are
        // verified in order of both kinds of evidence, a tier at a time ([`TIERS`]); the first
        // that passes and lies on the table is the next instance.
        // Those short of the 3D evidence or the image evidence needed are left out (their image
        // support is not worked out, or not to the end: the check stops once it must fail).
        doubtful.clear();
        let ranked = best_of(&seen, TIERS * p.hypotheses);
        let free_lines = FreeLines::new(scene, &free);
        let (mut best, mut sunk) = (None, None);
        for tier in ranked.chunks(p.hypotheses.max(1)) {
            // A tier's hypotheses verified in parallel (each on its own), in their order.
            use rayon::prelude::*;
            let verdicts: Vec<(Option<Candidate>, Vec<Candidate>)> = tier
                .par_iter()
                .map(|&start| {
                    let mut doubts = Vec::new();
                    (verified(model, scene, (&free, &free_lines), start, p, image, &mut doubts), doubts)
                })
                .collect();
            let mut passed = Vec::new();
            for (c, doubts) in verdicts {
                passed.extend(c);
                doubtful.extend(doubts);
            }
            // The highest rank first (of equals, the first verified).
            passed.sort_by(|a, b| b.rank().total_cmp(&a.rank()));
            for c in passed {
                match on_the_table(model, scene, &free, c, p, image) {
                    Ok(c) => {
                        best = Some(c);
                        break;
                    }
                    Err(c) => {
                        sunk.get_or_insert(c);
                    }
                }
            }
            if best.is_some() {
                break;
            }
        }
        // Where only readings through the table passed, the best of them is set aside as an
        // instance found would be (its lines no longer free) but not reported: the hypotheses
        // of the part truly there may all lie below its many variants, and rise only once
        // its lines are taken.
        let (c, on_table) = match (best, sunk) {
            (Some(c), _) => (c, true),
            (None, Some(c)) => (c, false),
            (None, None) => break,
        };
        let located = c.located(model, c.image_support);
        for &j in &located.scene_lines {
            free[j] = false;
        }
        if on_table {
            found.push(located);
        }
        doubtful.clear();
    }
    doubtful.sort_by(|a, b| b.score.total_cmp(&a.score));
    Search { found, doubtful, flat }
}

/// `c`, its pose refined on the image as well (3D lines alone leave flat parts a few degrees
/// off), if it then lies on the table ([`super::table`]), else refused. Judged after the
/// image's refinement, as a pose on a few 3D lines may lie several millimetres into the table
/// before it. (Trying the refused reading's half turns in its place, as a flat part turned over
/// runs along many of the same lines, found nothing more on the tuning seeds.)
fn on_the_table(
    model: &MatcherModel,
    scene: &[Seg],
    free: &[bool],
    c: Candidate,
    p: &MatchParams,
    image: Option<&ImageEvidence>,
) -> Result<Candidate, Candidate> {
    let c = match image {
        Some(ev) => in_image(model, scene, free, c, p, ev),
        None => c,
    };
    if through_table(p.table.as_ref(), model, &c.pose) { Err(c) } else { Ok(c) }
}

/// The candidate hypothesis `start` gives, refined on the free lines, if it has the 3D
/// evidence and the image evidence a located object needs; one with the 3D evidence only is
/// added to `doubtful`.
fn verified(
    model: &MatcherModel,
    scene: &[Seg],
    (free, free_lines): (&[bool], &FreeLines),
    start: Isometry3<f64>,
    p: &MatchParams,
    image: Option<&ImageEvidence>,
    doubtful: &mut Vec<Candidate>,
) -> Option<Candidate> {
    let (pose, score, pairs) = refine_among(model, scene, free_lines, start, p);
    let lines_seen = model_lines_of(&pairs).len();
    if score / model.total_length < p.min_support_fraction || lines_seen < p.min_support_lines {
        return None;
    }
    let min_image = image_support_needed(lines_seen, p);
    let image_support = match image {
        Some(ev) => match image_support_at_least(model, &pose, ev, min_image) {
            Some(s) if s >= min_image => s,
            // Well borne out in 3D, but a little off in the image: refined on the image before
            // it is judged there.
            _ if lines_seen >= MIN_LINES_TO_REFINE_DOUBTFUL
                && score / model.total_length >= MIN_SUPPORT_TO_REFINE_DOUBTFUL =>
            {
                let start = Candidate { pose, score, pairs: pairs.clone(), image_support: 0.0 };
                if let Some(c) = refined_in_image(model, scene, free, start, p, ev) {
                    return Some(c);
                }
                doubtful.push(Candidate { pose, score, pairs, image_support: 0.0 });
                return None;
            }
            _ => {
                doubtful.push(Candidate { pose, score, pairs, image_support: 0.0 });
                return None;
            }
        },
        None => 1.0,
    };
    Some(Candidate { pose, score, pairs, image_support })
}

/// The best-supported hypotheses are verified `hypotheses` at a time, the next as many only if
/// none of the first passes, up to this many times. In a pile the best supported can all lie
/// on other parts' lines, the part itself a little further down. On tuning seeds (`marvin
/// eval locate`, `widgets.toml` 1-500, `dense.toml` and `side_light.toml` 1-200, with
/// `max_instances` 4) two tiers located 96.7 / 87.2 / 90.0% -> 96.9 / 88.2 / 90.3% with 20 /
/// 26 / 5 -> 20 / 27 / 6 false reports. Verifying 24 at once found as many (96.9 / 88.3 /
/// 90.4%) for four times the instructions on `marvin bench vision`'s scene (+93 M against
/// +24 M over 6 matches, `callgrind`), 36 at once no more (dense 88.7%, 30 false).
const TIERS: usize = 2;

/// A candidate along at least this many model lines that the image does not bear out as it
/// stands is refined on the image and judged again, if its 3D lines also cover...
const MIN_LINES_TO_REFINE_DOUBTFUL: usize = 6;
/// ...this share of the model's length. On tuning seeds (`marvin eval locate`, `widgets.toml`
/// 1-500, `dense.toml` and `side_light.toml` 1-200) this found 2, 1 and 2 objects more (a
/// lone wedge on seven 3D lines, its pose along edgels for 0.497 of its wireframe as fitted to
/// them, 0.69 at the truth: seed 127) and put one false report right, losing none. Without the
/// share, a wrong second widget of the default scene was refined and searched on from, making
/// `match` 20% slower (`marvin bench vision`), and a U-channel was lost (dense seed 11); with
/// 5 lines, one false report more and three objects fewer in `dense`.
const MIN_SUPPORT_TO_REFINE_DOUBTFUL: f64 = 0.3;

/// `c` refined on the image (and its 3D lines), if it then passes the image check and still
/// has the support of a candidate.
fn refined_in_image(
    model: &MatcherModel,
    scene: &[Seg],
    free: &[bool],
    c: Candidate,
    p: &MatchParams,
    ev: &ImageEvidence,
) -> Option<Candidate> {
    let c = in_image(model, scene, free, c, p, ev);
    let lines = model_lines_of(&c.pairs).len();
    (c.image_support >= image_support_needed(lines, p)
        && c.score / model.total_length >= p.min_support_fraction
        && lines >= p.min_support_lines)
        .then_some(c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::Lcg;
    use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion};

    fn widget() -> MatcherModel {
        crate::matcher::fixtures::model("widget")
    }

    /// The model's lines in the scene: half of them hidden, the rest cut to fragments, their ends
    /// noised, some reversed, and random distractors added.
    fn scene_of(model: &MatcherModel, pose: &Isometry3<f64>, rng: &mut Lcg) -> Vec<Seg> {
        let mut scene = Vec::new();
        for (k, l) in model.lines.iter().enumerate() {
            if k % 2 == 1 {
                continue; // hidden
            }
            let t = l.transformed(pose);
            let (s0, s1) = (0.1 * rng.next(), 0.75 + 0.2 * rng.next());
            let (a, b) = (t.a + (t.b - t.a) * s0 + rng.noise(2e-4), t.a + (t.b - t.a) * s1 + rng.noise(2e-4));
            scene.push(if k % 3 == 0 { Seg::new(b, a) } else { Seg::new(a, b) });
        }
        for _ in 0..15 {
            let a = Point3::from(pose.translation.vector + rng.noise(0.15));
            scene.push(Seg::new(a, a + rng.noise(0.04)));
        }
        scene
    }

    #[test]
    fn the_pose_comes_back_within_the_noise() {
        let model = widget();
        let mut rng = Lcg(7);
        for (k, rpy) in [(0.0, 0.0, 0.3), (1.57, 0.0, -0.8), (0.4, 2.1, 1.0)].iter().enumerate() {
            let pose = Isometry3::from_parts(
                Translation3::new(0.03, -0.05, 0.85),
                UnitQuaternion::from_euler_angles(rpy.0, rpy.1, rpy.2),
            );
            let scene = scene_of(&model, &pose, &mut rng);
            let found = locate(&model, &scene, &MatchParams::default(), None);
            assert!(!found.is_empty(), "case {k}: not found");
            let got = &found[0].cam_from_model;
            let pos_err = (got.translation.vector - pose.translation.vector).norm();
            let rot_err = got.rotation.angle_to(&pose.rotation);
            assert!(pos_err < 1e-3, "case {k}: {:.2} mm off", pos_err * 1e3);
            assert!(rot_err < 0.5f64.to_radians(), "case {k}: {:.2} deg off", rot_err.to_degrees());
            assert_eq!(found.len(), 1, "case {k}: a second, false instance");
            // The grasp comes out in the camera frame, where the model's pose puts it.
            let (cam_from_gripper, width) = found[0].grasps[0];
            let expect = pose * model.grasps[0].0;
            assert!((cam_from_gripper.translation.vector - expect.translation.vector).norm() < 1e-3);
            assert_eq!(width, model.grasps[0].1);
        }
    }

    #[test]
    fn a_scene_of_distractors_alone_yields_nothing() {
        let model = widget();
        let mut rng = Lcg(3);
        let scene: Vec<Seg> = (0..40)
            .map(|_| {
                let a = Point3::new(0.0, 0.0, 0.9) + rng.noise(0.15);
                Seg::new(a, a + rng.noise(0.05))
            })
            .collect();
        assert!(locate(&model, &scene, &MatchParams::default(), None).is_empty());
    }

    /// A symmetric model seen from above: only the lines on faces turned towards a camera over
    /// it (the top and the sides), fragmented and noised. The pose comes back up to the model's
    /// symmetry, although its equivalent focus pairs are tabled once.
    #[test]
    fn a_symmetric_model_seen_from_one_side_is_found_up_to_its_symmetry() {
        let lib = mesh::Library::load_default().unwrap();
        for name in ["block", "hex_prism"] {
            let model = MatcherModel::from_model(lib.get(name).unwrap());
            let pose = Isometry3::from_parts(
                Translation3::new(-0.02, 0.04, 0.9),
                UnitQuaternion::from_euler_angles(2.6, 0.3, -0.7),
            );
            let mut rng = Lcg(11);
            let scene: Vec<Seg> = (0..model.lines.len())
                .filter(|&k| model.faces_camera(k, &pose))
                .map(|k| {
                    let t = model.lines[k].transformed(&pose);
                    Seg::new(t.a + (t.b - t.a) * 0.05 + rng.noise(2e-4), t.a + (t.b - t.a) * 0.9 + rng.noise(2e-4))
                })
                .collect();
            let found = locate(&model, &scene, &MatchParams::default(), None);
            assert_eq!(found.len(), 1, "{name}");
            // Equivalent under the symmetry: every model line lands on a model line of the truth.
            let got = found[0].cam_from_model;
            for l in &model.lines {
                let (a, b) = (got * l.a, got * l.b);
                let on_truth = model.lines.iter().any(|m| {
                    let (ma, mb) = (pose * m.a, pose * m.b);
                    ((ma - a).norm() < 2e-3 && (mb - b).norm() < 2e-3)
                        || ((ma - b).norm() < 2e-3 && (mb - a).norm() < 2e-3)
                });
                assert!(on_truth, "{name}: a line of the located model is not on the true one");
            }
        }
    }

    /// A widget whose 3D lines all lie 3.5 mm off its edges (as a slightly wrong stereo depth
    /// puts them): the pose fitted to them misses the image's edgels, but refined on the image
    /// it is found where the edgels put it.
    #[test]
    fn a_pose_a_little_off_in_the_image_is_refined_there_before_it_is_judged() {
        let model = widget();
        let cam = crate::matcher::fixtures::camera_at(Point3::new(0.0, -0.6, 0.6));
        let world_from_model = Isometry3::from_parts(
            Translation3::new(0.01, -0.02, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
        );
        let truth = cam.cam_from_world() * world_from_model;
        let (edges, lines) = crate::matcher::verify::drawn::model_edges(&model, &truth, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines);
        let off = nalgebra::Vector3::new(0.0035, 0.0, 0.0);
        let scene: Vec<Seg> = (0..model.lines.len())
            .filter(|&k| model.faces_camera(k, &truth))
            .map(|k| {
                let t = model.lines[k].transformed(&truth);
                Seg::new(t.a + off, t.b + off)
            })
            .collect();
        let p = MatchParams::default();
        let as_fitted = locate(&model, &scene, &p, None);
        assert_eq!(as_fitted.len(), 1);
        let fitted = as_fitted[0].cam_from_model;
        assert!(
            image_support_at_least(&model, &fitted, &ev, 0.0).unwrap() < p.min_image_support,
            "the pose fitted to the 3D lines alone must miss the edgels for this test to mean anything"
        );
        let found = locate(&model, &scene, &p, Some(&ev));
        assert_eq!(found.len(), 1, "found, refined on the image");
        let err = (found[0].cam_from_model.translation.vector - truth.translation.vector).norm();
        assert!(err < 1e-3, "{:.2} mm from the truth", err * 1e3);
    }
}
