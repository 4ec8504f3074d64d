//! A second look for objects stereo gave too few 3D lines to seed from: one unexplained 3D line
//! and one image line that stereo could not lift (an edge near the rasters' direction) meeting
//! it at a corner.
//!
//! The 3D line, taken as a model edge running out of a corner, fixes the pose but for a turn
//! about the line and a shift along it. The image line's plane through the camera must hold the
//! model edge that leaves the same corner: its direction fixes the turn (up to two solutions of
//! `A cos θ + B sin θ + C = 0`) and the corner itself, which lies in that plane, fixes the shift.
//! The pose is then refined on the image's edgels and that 3D line ([`super::image_fit`]).
//! Such poses rest on little 3D evidence, so they must be borne out by the image: most of the
//! camera-facing wireframe along edgels. Where 3D lines lie along two or more of its edges, 70%
//! of the part that the objects already located leave in view (parts seen at all are mostly
//! partly hidden: counting the hidden part as unseen missed 3 of the 18 objects left over 50
//! scenes, and one of 13 over seeds 51-80, with no false report gained by excusing it); where
//! along one, 85% of all of it, none excused (excused, that found one more object and three
//! false reports over 110 scenes), or 75% of the part in view where the pose rests flat on the
//! table (few poses from one line do by chance). Either way no more than half of its wireframe may run along
//! the image edges of objects already located ([`Explained`]): a part read into
//! another's corner shows nothing of its own (an L-bracket on a U-channel, seed 109).

use super::image_fit::{SEARCH_PX, refine_in_image};
use super::model::{Corner, Located, MatchParams, MatcherModel, Seg, eye_of};
use super::occlusion::{MIN_IN_VIEW, Solid};
use super::support::{model_lines_of, scene_lines_of, support};
use super::table::{hopelessly_sunk, turn_between};
use super::verify::{
    Explained, ImageEvidence, ImageLine, MAX_EXPLAINED, image_support_at_least, image_support_unhidden,
};
use nalgebra::{Isometry3, Matrix3, Point2, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// The image line's corner end must lie this close to where it meets the 3D line's image (px).
const CORNER_PX: f64 = 8.0;
/// The corner may lie this far beyond the 3D line's imaged ends (px): stereo loses line ends.
const BEYOND_PX: f64 = 40.0;
/// A pose from a second look must run along edgels for this much of its camera-facing
/// wireframe if one model line has 3D support...
const MIN_IMAGE_SUPPORT: f64 = 0.85;
/// ...and for this much of the part in view if two or more have (measured over seeds 1-50 and
/// 51-80, before occlusion was taken into account: located 0.922 -> 0.934 and 0.922 -> 0.932
/// with the same false reports; 0.65 added false reports).
const MIN_IMAGE_SUPPORT_TWO_LINES: f64 = 0.7;
/// ...and, with one, for this much of the part in view where it rests flat on the table (as
/// [`super::table_look`] asks). On the tuning seeds (`marvin eval locate`,
/// `widgets.toml` 1-500, `dense.toml` and `side_light.toml` 1-200) this located 97.9 / 90.7 /
/// 91.7% -> 98.0 / 90.9 / 92.7% with 11 / 20 / 5 -> 11 / 20 / 6 false reports: under the side
/// light most parts missed have one 3D line, yet the image shows them well.
const FLAT_MIN_IMAGE_SUPPORT: f64 = super::table_look::MIN_IMAGE_SUPPORT;
/// A pose from a second look is refined on the image if this much of it already runs along edgels.
const MIN_IMAGE_SUPPORT_TO_REFINE: f64 = 0.6;
/// Candidates verified per model.
const CANDIDATES: usize = 8;

/// Where the lines through `p0`-`p1` and `q0`-`q1` cross, as a parameter along the first.
fn crossing(p0: &Point2<f64>, p1: &Point2<f64>, q0: &Point2<f64>, q1: &Point2<f64>) -> Option<(f64, Point2<f64>)> {
    let (d, e) = (p1 - p0, q1 - q0);
    let den = d.x * e.y - d.y * e.x;
    if den.abs() < 1e-9 {
        return None;
    }
    let w = q0 - p0;
    let s = (w.x * e.y - w.y * e.x) / den;
    Some((s, p0 + d * s))
}

/// The turns (model to `cam`) putting `c.line` along scene line `s` (out of the corner along
/// `u_out`) and `c.other` in the plane of image line `l`, and where they put the corner: the
/// poses [`Corner::pose`] makes of them.
fn turns(
    model_line: &Seg,
    c: &Corner,
    s: &Seg,
    u_out: &Vector3<f64>,
    l: &ImageLine,
) -> Option<([Rotation3<f64>; 2], Point3<f64>)> {
    // First what the corner's turn does not change (most corners fail here, and the turn costs
    // trigonometry): the scene line must cross the image line's plane...
    let (n, u) = (l.normal, *u_out);
    if n.dot(&u).abs() < 0.05 {
        return None;
    }
    // ...where the corner lies on the scene line, and the fragment (starting at s0) must lie
    // along the model edge, out of the corner.
    let s0 = if u.dot(&s.dir) > 0.0 { s.a } else { s.b };
    let lambda = -n.dot(&s0.coords) / n.dot(&u);
    let slack = 0.012;
    if -lambda < -slack || -lambda > model_line.len - s.len + slack {
        return None;
    }
    let r0 = turn_between(&c.out, u_out);
    let v = r0 * c.other_out;
    let (a, b, cc) = (n.dot(&v) - n.dot(&u) * u.dot(&v), n.dot(&u.cross(&v)), n.dot(&u) * u.dot(&v));
    let rho = (a * a + b * b).sqrt();
    if rho < 1e-9 || cc.abs() > rho {
        return None;
    }
    // The turns by base +- delta, base = atan2(b, a) and delta = acos(-cc / rho), by their
    // cosines and sines (the sum and difference formulas): trigonometry was a third of the
    // second look's time.
    let (cos_base, sin_base) = (a / rho, b / rho);
    let cos_delta = -cc / rho;
    let sin_delta = (1.0 - cos_delta * cos_delta).max(0.0).sqrt();
    let turn = |sign: f64| {
        let cos = cos_base * cos_delta - sign * sin_base * sin_delta;
        let sin = sin_base * cos_delta + sign * cos_base * sin_delta;
        turn_about(&u, cos, sin) * r0
    };
    Some(([turn(1.0), turn(-1.0)], s0 + u * lambda))
}

/// The turn about unit vector `axis` by the angle of cosine `cos` and sine `sin`.
fn turn_about(axis: &Vector3<f64>, cos: f64, sin: f64) -> Rotation3<f64> {
    let m = Matrix3::identity() * cos + axis.cross_matrix() * sin + axis * axis.transpose() * (1.0 - cos);
    Rotation3::from_matrix_unchecked(m)
}

impl Corner {
    /// The pose that turns the model by `r` and puts the corner at `at` (`cam`).
    fn pose(&self, r: &Rotation3<f64>, at: &Point3<f64>) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(at - r * self.corner), UnitQuaternion::from_rotation_matrix(r))
    }
}

/// Whether the model, turned by `r` with the corner at `at`, images the corner's other edge
/// along image line `l`: out of the corner the way the line runs, and at least as long (the
/// image line is some stretch of it). Half the turns [`turns`] finds point the edge the other
/// way, and an image line's plane holds many model edges that end well short of it; ruling
/// these out first spares their image check, most of the second look's time. (Tested first,
/// before the pose is made: 90% of the turns on `marvin bench vision`'s scene fail it.)
fn runs_along((r, at): (&Rotation3<f64>, &Point3<f64>), c: &Corner, l: &ImageLine, ev: &ImageEvidence) -> bool {
    let (Some(corner), Some(end)) =
        (ev.cam.project_cam(at), ev.cam.project_cam(&(at + r * (c.other_out * c.other_len))))
    else {
        return false;
    };
    let far = if (l.a - corner).norm() < (l.b - corner).norm() { l.b } else { l.a };
    let (edge, line) = (end - corner, far - corner);
    edge.dot(&line) > 0.0 && line.norm() <= edge.norm() + CORNER_PX
}

/// Objects of `model` found from the unclaimed 3D lines and the unlifted image lines, with the
/// `solids` of the objects located so far hiding what lies behind them and their image edges
/// (`explained`) counting for none of it.
pub fn locate(
    model: &MatcherModel,
    scene: &[Seg],
    claimed: &[bool],
    p: &MatchParams,
    ev: &ImageEvidence,
    (solids, explained): (&[Solid], &Explained),
) -> Vec<Located> {
    locate_refining(model, scene, claimed, p, ev, (solids, explained), (MIN_IMAGE_SUPPORT_TO_REFINE, None))
}

/// [`locate`], refining only the poses that already run along edgels for `min_to_refine` of
/// their camera-facing wireframe (a search that will ask more of the result may ask more of
/// the start, and refines fewer) and, if `within` is given, whose model's centre lies in that
/// sphere (`cam` frame).
pub(crate) fn locate_refining(
    model: &MatcherModel,
    scene: &[Seg],
    claimed: &[bool],
    p: &MatchParams,
    ev: &ImageEvidence,
    (solids, explained): (&[Solid], &Explained),
    (min_to_refine, within): (f64, Option<(Point3<f64>, f64)>),
) -> Vec<Located> {
    let (centre, radius) = model.bounding_sphere();
    let inside = |pose: &Isometry3<f64>| within.is_none_or(|(c, r)| (pose * centre - c).norm() <= r);
    // A pose puts a corner (within `radius` of the model's centre) on the scene line, so a line
    // further than that from the sphere the centre must lie in gives none inside it.
    let may_reach = |s: &Seg| {
        within.is_none_or(|(c, r)| {
            let w = c - s.a;
            (w - s.dir * w.dot(&s.dir)).norm() <= r + radius + 1e-9
        })
    };
    let hiding: Vec<&Solid> = solids.iter().collect();
    let corners = &model.corner_edges;
    // The poses from each scene line that pass the image check, with their support in view.
    let from_line = |j: usize, s: &Seg| {
        let mut passed = Vec::new();
        if claimed[j] || s.len < p.min_seed_length || !may_reach(s) {
            return passed;
        }
        let (Some(pa), Some(pb)) = (ev.cam.project_cam(&s.a), ev.cam.project_cam(&s.b)) else { return passed };
        let len_px = (pb - pa).norm();
        if len_px < 1.0 {
            return passed;
        }
        for l in &ev.lines {
            let Some((t, x)) = crossing(&pa, &pb, &l.a, &l.b) else { continue };
            let beyond = BEYOND_PX / len_px;
            if t < -beyond || t > 1.0 + beyond {
                continue;
            }
            // The image line must start at the corner.
            if (l.a - x).norm() > CORNER_PX && (l.b - x).norm() > CORNER_PX {
                continue;
            }
            // Out of the corner, the 3D line runs towards its far imaged end.
            let u_out = if t < 0.5 { s.dir } else { -s.dir };
            for c in corners {
                let ml = &model.lines[c.line];
                if s.len > ml.len + 0.012 {
                    continue;
                }
                // Both edges seen (the 3D line's and the image line's), the part out of the
                // table's depth, before the image is asked.
                let fits = |pose: &Isometry3<f64>| {
                    let eye = eye_of(pose);
                    inside(pose)
                        && model.may_be_seen(c.line, &eye)
                        && model.may_be_seen(c.other, &eye)
                        && !hopelessly_sunk(p.table.as_ref(), model, pose)
                };
                let Some((rs, at)) = turns(ml, c, s, &u_out, l) else { continue };
                let along = rs.iter().filter(|r| runs_along((r, &at), c, l, ev));
                for pose in along.map(|r| c.pose(r, &at)).filter(fits) {
                    // The pose is only as good as one short 3D line's direction: refined on
                    // the image (and that line) before the strict image check, if it is near
                    // enough to start from.
                    if image_support_at_least(model, &pose, ev, min_to_refine).is_none() {
                        continue;
                    }
                    let Some(pose) = refine_in_image(model, &pose, scene, &[(c.line, j)], ev, SEARCH_PX) else {
                        continue;
                    };
                    let (in_view, share) = image_support_unhidden(model, &pose, ev, &hiding);
                    if in_view >= MIN_IMAGE_SUPPORT_TWO_LINES && share >= MIN_IN_VIEW {
                        passed.push((in_view, pose));
                    }
                }
            }
        }
        passed
    };
    // Scene lines in parallel; their poses kept in the lines' order, as one after the other.
    use rayon::prelude::*;
    let per_line: Vec<Vec<(f64, Isometry3<f64>)>> =
        scene.par_iter().enumerate().map(|(j, s)| from_line(j, s)).collect();
    let mut best: Vec<(f64, Isometry3<f64>)> = Vec::new();
    for (in_view, pose) in per_line.into_iter().flatten() {
        keep(&mut best, in_view, pose);
    }
    let free: Vec<bool> = claimed.iter().map(|c| !c).collect();
    best.into_iter()
        .filter_map(|(in_view, pose)| {
            let (score, pairs) = support(model, &pose, scene, &free, p);
            let (used, model_lines) = (scene_lines_of(&pairs), model_lines_of(&pairs));
            if explained.share(model, &pose, ev.cam) > MAX_EXPLAINED {
                return None;
            }
            // One 3D line is little to go on: the whole camera-facing wireframe must be borne
            // out, none of it excused as hidden; unless the part rests flat on the table, which
            // few poses from one line and an image line do by chance: then what the objects
            // located leave in view, as the table look asks.
            let image_support = match model_lines.len() {
                0 => return None,
                1 if in_view >= FLAT_MIN_IMAGE_SUPPORT && rests_flat_on(p.table.as_ref(), model, &pose) => in_view,
                1 => image_support_at_least(model, &pose, ev, MIN_IMAGE_SUPPORT)?,
                _ => in_view,
            };
            Some(Located {
                model: model.name.clone(),
                cam_from_model: pose,
                support: score,
                support_fraction: score / model.total_length,
                scene_lines: used,
                image_support,
                grasps: model.grasps_at(&pose),
            })
        })
        // The best by 3D support times image support, as the first pass ranks: a part turned
        // over can fit the image as well but rarely the 3D lines too.
        .reduce(|a, b| if b.support * b.image_support > a.support * a.image_support { b } else { a })
        .into_iter()
        .collect()
}

/// Whether `model` at `pose` rests flat on the table, if one is known.
fn rests_flat_on(table: Option<&super::model::Table>, model: &MatcherModel, pose: &Isometry3<f64>) -> bool {
    table.is_some_and(|t| super::table::rests_flat(t, model, pose, super::table_look::REST_M))
}

fn keep(best: &mut Vec<(f64, Isometry3<f64>)>, score: f64, pose: Isometry3<f64>) {
    let at = best.iter().position(|(s, _)| *s < score).unwrap_or(best.len());
    best.insert(at, (score, pose));
    best.truncate(CANDIDATES);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The turns made without trigonometry agree with nalgebra's made with it: between random
    /// directions (and nearly opposite ones, the fallback), and about random axes by random angles.
    #[test]
    fn turns_without_trigonometry_agree_with_nalgebras() {
        let mut rng = crate::matcher::fixtures::Lcg(5);
        for k in 0..500 {
            let from = rng.noise(1.0).normalize();
            let to = if k % 50 == 0 { (-from + rng.noise(1e-5)).normalize() } else { rng.noise(1.0).normalize() };
            let ours = turn_between(&from, &to);
            assert!((ours * from - to).norm() < 1e-9, "does not take {from} onto {to}");
            let theirs = Rotation3::rotation_between(&from, &to).unwrap();
            assert!((ours.matrix() - theirs.matrix()).norm() < 1e-9, "not the least turn");
            let (axis, angle) = (rng.noise(1.0).normalize(), (rng.next() - 0.5) * 7.0);
            let about = turn_about(&axis, angle.cos(), angle.sin());
            let theirs = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle);
            assert!((about.matrix() - theirs.matrix()).norm() < 1e-12);
        }
    }

    /// A block resting on a table (the world's z = 0) seen from 0.85 m off, the camera looking
    /// down: the block, the camera, its pose (`cam_from_model`) and one 3D line, 80% of its
    /// longest camera-facing edge.
    fn block_on_one_line() -> (MatcherModel, mesh::PinholeCamera, Isometry3<f64>, Vec<Seg>) {
        let model = crate::matcher::fixtures::model("block");
        let cam = crate::matcher::fixtures::camera_at(Point3::new(0.0, -0.6, 0.6));
        let lowest = model.lines.iter().flat_map(|l| [l.a.z, l.b.z]).fold(f64::MAX, f64::min);
        let world_from_model = Isometry3::from_parts(
            Translation3::new(0.01, -0.02, -lowest),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5),
        );
        let pose = cam.cam_from_world() * world_from_model;
        let k = (0..model.lines.len())
            .filter(|&k| model.faces_camera(k, &pose))
            .max_by(|&a, &b| model.lines[a].len.total_cmp(&model.lines[b].len))
            .unwrap();
        let t = model.lines[k].transformed(&pose);
        let scene = vec![Seg::new(t.a + (t.b - t.a) * 0.1, t.a + (t.b - t.a) * 0.9)];
        (model, cam, pose, scene)
    }

    /// The block on its one 3D line, with edgels along every camera-facing edge in the image
    /// and an image line along each of them.
    #[test]
    fn one_3d_line_and_the_image_find_a_block() {
        let (model, cam, pose, scene) = block_on_one_line();
        let (edges, lines) = crate::matcher::verify::drawn::model_edges(&model, &pose, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines);
        let nothing_located = Explained::of([], ev.cam);
        let found = locate(&model, &scene, &[false], &MatchParams::default(), &ev, (&[], &nothing_located));
        assert_eq!(found.len(), 1);
        // Right up to the block's symmetry: every located edge lies on a true edge.
        assert!(
            crate::matcher::fixtures::on_its_lines(&model, &found[0].cam_from_model, &pose, 1e-3),
            "a located edge is off the block"
        );
    }

    /// Sought within a sphere round the block's centre (as the rival reading seeks), the block
    /// is found from its one 3D line, an edge a block's half-size from that centre; within a
    /// sphere as small placed 5 cm off, nothing is.
    #[test]
    fn within_a_sphere_a_line_reaching_it_still_finds_the_block() {
        let (model, cam, pose, scene) = block_on_one_line();
        let (edges, lines) = crate::matcher::verify::drawn::model_edges(&model, &pose, &cam);
        let ev = ImageEvidence::new(&cam, &edges, lines);
        let nothing_located = Explained::of([], ev.cam);
        let centre = pose * model.bounding_sphere().0;
        let seek = |at: Point3<f64>| {
            let (p, located) = (MatchParams::default(), (&[][..], &nothing_located));
            locate_refining(
                &model,
                &scene,
                &[false],
                &p,
                &ev,
                located,
                (MIN_IMAGE_SUPPORT_TO_REFINE, Some((at, 0.005))),
            )
        };
        assert!((scene[0].a - centre).norm() > 0.01, "the line runs through the sphere");
        assert_eq!(seek(centre).len(), 1, "not found within the sphere round it");
        assert!(seek(centre + Vector3::new(0.05, 0.0, 0.0)).is_empty(), "found 5 cm off");
    }

    /// The same block with the image's edgels cut off on one side (as a part not located might
    /// hide them), leaving 75-85% of its wireframe along edgels: on its one 3D line it is found
    /// only where the table is known, for it rests flat on it.
    #[test]
    fn one_3d_line_finds_a_part_partly_shown_only_flat_on_the_table() {
        let (model, cam, pose, scene) = block_on_one_line();
        let (all_edges, lines) = crate::matcher::verify::drawn::model_edges(&model, &pose, &cam);
        // The edgels left of a cut moved in from the right until under 85% of the wireframe
        // runs along them.
        let cut_at = |x_cut: f32| {
            let mut edges = crate::front_end::canny::EdgeMap::new(all_edges.width, all_edges.height);
            for (e, &pixel) in all_edges.edgels.iter().zip(&all_edges.pixel) {
                if e.x < x_cut {
                    edges.push(pixel as usize, *e);
                }
            }
            edges
        };
        let shown = |edges: &crate::front_end::canny::EdgeMap| {
            crate::matcher::verify::image_support(&model, &pose, &ImageEvidence::new(&cam, edges, lines.clone()))
        };
        let right = all_edges.edgels.iter().map(|e| e.x).fold(f32::MIN, f32::max);
        let edges = (0..200).map(|s| cut_at(right - s as f32)).find(|e| shown(e) < 0.85).unwrap();
        let share = shown(&edges);
        assert!((0.75..0.85).contains(&share), "{share} of the wireframe shown");
        let ev = ImageEvidence::new(&cam, &edges, lines.clone());
        let nothing_located = Explained::of([], ev.cam);
        let table = super::super::model::Table::from_cam_from_table(&cam.cam_from_world());
        let with_table = MatchParams { table: Some(table), ..MatchParams::default() };
        let found = locate(&model, &scene, &[false], &with_table, &ev, (&[], &nothing_located));
        assert_eq!(found.len(), 1, "not found with the table known");
        let middle = |p: &Isometry3<f64>| p * model.bounding_sphere().0;
        assert!((middle(&found[0].cam_from_model) - middle(&pose)).norm() < 1e-3, "found off the block");
        let without = locate(&model, &scene, &[false], &MatchParams::default(), &ev, (&[], &nothing_located));
        assert!(without.is_empty(), "found on one line with 85% of the wireframe unshown, no table known");
    }
}
