//! The stereo polish's tests: poses pulled onto both images, and turns taken in stereo.

use super::*;
use crate::front_end::canny::EdgeMap;
use crate::matcher::fixtures::{model, verged_pair as pair};
use crate::matcher::model::Table;
use crate::matcher::verify::{RightImage, drawn::model_edges};
use nalgebra::{Translation3, Unit, UnitQuaternion, Vector3};
use std::f64::consts::{FRAC_PI_2, PI};

fn report(model: &MatcherModel, pose: Isometry3<f64>) -> Located {
    Located {
        model: model.name.clone(),
        cam_from_model: pose,
        support: 0.0,
        support_fraction: 0.3,
        scene_lines: Vec::new(),
        image_support: 1.0,
        grasps: Vec::new(),
    }
}

/// The model's lines at `pose`, as the 3D lines of a scene.
fn true_lines(model: &MatcherModel, pose: &Isometry3<f64>) -> Vec<Seg> {
    model.lines.iter().map(|l| Seg::new(pose * l.a, pose * l.b)).collect()
}

/// A wedge lying on the table before the verged pair: the wedge, the left and right
/// cameras, its pose (the left camera's frame) and the right camera's frame from the left's.
fn wedge_on_table() -> (MatcherModel, mesh::PinholeCamera, mesh::PinholeCamera, Isometry3<f64>, Isometry3<f64>) {
    let (left, right) = pair();
    let truth = left.cam_from_world()
        * Isometry3::from_parts(Translation3::new(0.01, 0.02, 0.0), UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7));
    let right_from_cam = right.cam_from_world() * left.world_from_cam;
    (model("wedge"), left, right, truth, right_from_cam)
}

/// A model, the left and right cameras, the table, the model's pose and the right camera's
/// frame from the left's.
type OnTable = (MatcherModel, mesh::PinholeCamera, mesh::PinholeCamera, Table, Isometry3<f64>, Isometry3<f64>);

/// [`wedge_on_table`] with the table known, the wedge's bottom on its top.
fn wedge_resting_on_table() -> OnTable {
    let (wedge, left, right, on_the_floor, right_from_cam) = wedge_on_table();
    let table = Table::from_cam_from_table(&left.cam_from_world());
    // The fixture's pose puts the model's origin on the top; its bottom goes there.
    let up = Vector3::from(table.up);
    let truth =
        Translation3::from(-up * super::super::table::lowest_height(&table, &wedge, &on_the_floor)) * on_the_floor;
    (wedge, left, right, table, truth, right_from_cam)
}

/// `model` reported at `pose`, turned in stereo on `lines` and `ev`: whether it was turned,
/// and the pose it ends at.
fn turned_in_stereo(
    model: &MatcherModel,
    (lines, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    pose: Isometry3<f64>,
) -> (Vec<bool>, Isometry3<f64>) {
    let mut kept = [report(model, pose)];
    let turns = crate::matcher::shading::TurnedCandidates::default();
    let turned = turn_in_stereo(std::slice::from_ref(model), (lines, p), ev, &turns, &mut kept);
    (turned, kept[0].cam_from_model)
}

/// `wedge` reported at `pose` among three blocks resting on the table beside it (which give
/// the scene its resting level), turned in stereo on `lines` and `ev`: whether the wedge was
/// turned, and the pose it ends at.
fn turned_among_blocks(
    wedge: &MatcherModel,
    left: &mesh::PinholeCamera,
    (lines, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    pose: Isometry3<f64>,
) -> (bool, Isometry3<f64>) {
    let block = model("block");
    let beside = |x: f64| report(&block, left.cam_from_world() * Isometry3::translation(x, -0.1, 0.015));
    let models = [wedge.clone(), block.clone()];
    let mut kept = [report(wedge, pose), beside(-0.12), beside(0.14), beside(-0.22)];
    let turns = crate::matcher::shading::TurnedCandidates::default();
    let turned = turn_in_stereo(&models, (lines, p), ev, &turns, &mut kept);
    (turned[0], kept[0].cam_from_model)
}

/// Asserts that `model` misread at `poses.0` is turned in stereo back onto the truth, `poses.1`.
fn assert_turned_back(
    model: &MatcherModel,
    (lines, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    (misread, truth): (Isometry3<f64>, Isometry3<f64>),
) {
    let (turned, got) = turned_in_stereo(model, (lines, p), ev, misread);
    let (mm, deg) = off_by(&truth, &got);
    assert!(turned == [true] && mm < 0.05 && deg < 0.05, "turned back to {mm:.3} mm, {deg:.3} deg off");
}

/// Of `lines`, those `model` at `pose` lies along for more than half their length.
fn lines_along(model: &MatcherModel, pose: &Isometry3<f64>, lines: Vec<Seg>, p: &MatchParams) -> Vec<Seg> {
    lines
        .into_iter()
        .filter(|l| support_at(model, pose, std::slice::from_ref(l), p).0 > 0.5 * (l.b - l.a).norm())
        .collect()
}

/// `pose` 4 deg and 2 mm off, as a 3D line leaning on a silhouette leaves a report.
fn off_a_few_degrees(pose: &Isometry3<f64>) -> Isometry3<f64> {
    Translation3::new(0.002, 0.0, -0.001) * pose * Isometry3::rotation(Vector3::new(0.05, -0.04, 0.02))
}

fn off_by(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    let e = a.inverse() * b;
    (e.translation.vector.norm() * 1e3, e.rotation.angle().to_degrees())
}

/// A wedge reported 4 deg and 2 mm off (as a 3D line leaning on a silhouette leaves it)
/// comes back onto its edgels in both images, within a few hundredths of a millimetre and
/// degree, and its grasps move with it; with the left image alone nothing moves.
#[test]
fn a_report_a_few_degrees_off_is_polished_onto_both_images() {
    let (wedge, left, right, truth, right_from_cam) = wedge_on_table();
    let (left_edges, _) = model_edges(&wedge, &truth, &left);
    let (right_edges, _) = model_edges(&wedge, &(right_from_cam * truth), &right);
    let lev = ImageEvidence::new(&left, &left_edges, Vec::new());
    let start = off_a_few_degrees(&truth);
    assert!(off_by(&truth, &start).1 > 3.5);

    let mut alone = [report(&wedge, start)];
    let (lines, p) = (true_lines(&wedge, &truth), MatchParams::default());
    polish_in_stereo(std::slice::from_ref(&wedge), (&lines, &p), &lev, &mut alone);
    assert_eq!(alone[0].cam_from_model, start, "the left image alone polishes nothing");

    let both = lev.with_right(RightImage { ev: ImageEvidence::new(&right, &right_edges, Vec::new()), right_from_cam });
    let mut kept = [report(&wedge, start)];
    polish_in_stereo(std::slice::from_ref(&wedge), (&lines, &p), &both, &mut kept);
    let (mm, deg) = off_by(&truth, &kept[0].cam_from_model);
    assert!(mm < 0.05 && deg < 0.05, "{mm:.3} mm, {deg:.3} deg off");
    for ((g, w), (mg, mw)) in kept[0].grasps.iter().zip(&wedge.grasps) {
        assert_eq!((*g, *w), (kept[0].cam_from_model * mg, *mw));
    }
    assert_eq!(kept[0].grasps.len(), wedge.grasps.len());

    // Only the reports marked are polished.
    let mut marked = [report(&wedge, start), report(&wedge, start)];
    polish_those(std::slice::from_ref(&wedge), (&lines, &p), &both, &mut marked, &[false, true]);
    assert_eq!(marked[0].cam_from_model, start, "the report not marked stands");
    let (mm, deg) = off_by(&truth, &marked[1].cam_from_model);
    assert!(mm < 0.05 && deg < 0.05, "the marked one: {mm:.3} mm, {deg:.3} deg off");
}

/// Where the 3D lines lean with a report a few degrees off (they are its own lines, and
/// few of them lie along the truth's), the polish onto the truth loses their support and is
/// kept all the same, both images showing it more sharply; where the left image shows the
/// report's pose and only the right the truth, the lines hold the report near where it is.
#[test]
fn a_polish_that_loses_leaning_3d_lines_is_kept_where_both_images_bear_it_out() {
    let (wedge, left, right, truth, right_from_cam) = wedge_on_table();
    let start = off_a_few_degrees(&truth);
    let (lines, p) = (true_lines(&wedge, &start), MatchParams::default());
    let support = |pose: &Isometry3<f64>| support_at(&wedge, pose, &lines, &p).0;
    assert!(support(&truth) < KEEP_SUPPORT * support(&start), "the lines lean with the report");
    let evidence = |left_pose: &Isometry3<f64>| {
        let (left_edges, _) = model_edges(&wedge, left_pose, &left);
        let (right_edges, _) = model_edges(&wedge, &(right_from_cam * truth), &right);
        (left_edges, right_edges)
    };
    let polish = |(left_edges, right_edges): &(_, _)| {
        let ev = ImageEvidence::new(&left, left_edges, Vec::new())
            .with_right(RightImage { ev: ImageEvidence::new(&right, right_edges, Vec::new()), right_from_cam });
        let mut kept = [report(&wedge, start)];
        polish_in_stereo(std::slice::from_ref(&wedge), (&lines, &p), &ev, &mut kept);
        kept[0].cam_from_model
    };
    let (mm, deg) = off_by(&truth, &polish(&evidence(&truth)));
    assert!(mm < 0.05 && deg < 0.05, "both images show the truth: polished {mm:.3} mm, {deg:.3} deg off it");
    let (mm, deg) = off_by(&start, &polish(&evidence(&start)));
    assert!(mm < 0.5 && deg < 0.5, "the left image shows the report: polished {mm:.3} mm, {deg:.3} deg off it");
}

/// A wedge whose left image shows it a few degrees off (as the looks left it, fitted there),
/// where the right image and the 3D lines show the truth: the polish on both images alone is
/// not sharper in both (the left image pulls it one way, the right the other; it slid 8.6 mm
/// off), and held to its 3D lines it comes within half a millimetre and degree of the truth.
#[test]
fn a_report_fitted_to_the_left_image_alone_is_held_to_its_3d_lines_onto_the_truth() {
    let (wedge, left, right, truth, right_from_cam) = wedge_on_table();
    let start = off_a_few_degrees(&truth);
    let (lines, p) = (true_lines(&wedge, &truth), MatchParams::default());
    let (left_edges, _) = model_edges(&wedge, &start, &left);
    let (right_edges, _) = model_edges(&wedge, &(right_from_cam * truth), &right);
    let ev = ImageEvidence::new(&left, &left_edges, Vec::new())
        .with_right(RightImage { ev: ImageEvidence::new(&right, &right_edges, Vec::new()), right_from_cam });
    let (views, solids) = stereo_views(std::slice::from_ref(&wedge), &ev, &[report(&wedge, start)]).unwrap();
    let others = others_than(&solids, 0);
    let alone = polished(&wedge, &start, &others, &views, None);
    let held = polished_or_held(&wedge, &start, (&lines, &p), &others, &views, None);
    let ((_, deg_alone), (mm, deg)) = (off_by(&truth, &alone), off_by(&truth, &held));
    assert!(!sharper_in_both(&wedge, (&start, &alone), &views, &others), "the left image disagrees");
    assert!(deg < 0.5 && mm < 0.5, "held: {mm:.2} mm, {deg:.2} deg off (alone {deg_alone:.2} deg)");
    let mut kept = [report(&wedge, start)];
    polish_in_stereo(std::slice::from_ref(&wedge), (&lines, &p), &ev, &mut kept);
    assert_eq!(kept[0].cam_from_model, held, "the report takes the held polish");
}

/// A wedge read resting on its slope where it rests on its bottom (a turn about no axis of
/// its box), both images showing it as it lies: turned back in stereo; read as it lies, it
/// stays.
#[test]
fn a_wedge_read_on_its_slope_is_turned_back_by_both_images() {
    let (wedge, left, right, truth, right_from_cam) = wedge_on_table();
    let (left_edges, _) = model_edges(&wedge, &truth, &left);
    let (right_edges, _) = model_edges(&wedge, &(right_from_cam * truth), &right);
    let ev = ImageEvidence::new(&left, &left_edges, Vec::new())
        .with_right(RightImage { ev: ImageEvidence::new(&right, &right_edges, Vec::new()), right_from_cam });
    let bottom_to_slope = crate::matcher::turns::of(&wedge)[3];
    let (mm, deg) = off_by(&truth, &(truth * bottom_to_slope));
    assert!(mm > 5.0 && deg > 170.0, "the misreading lies {mm:.1} mm, {deg:.0} deg off");
    let (lines, p) = (true_lines(&wedge, &truth), MatchParams::default());
    let turn = |pose: Isometry3<f64>| turned_in_stereo(&wedge, (&lines, &p), &ev, pose);
    let (turned, got) = turn(truth * bottom_to_slope);
    let (mm, deg) = off_by(&truth, &got);
    assert!(turned == [true] && mm < 0.05 && deg < 0.05, "turned back to {mm:.3} mm, {deg:.3} deg off");
    assert_eq!(turn(truth), (vec![false], truth), "read as it lies, it stays");
}

/// The wedge of [`wedge_on_table`] read resting on its slope, both images showing it as it
/// lies, on the 3D lines the two readings share and the misreading's own lines, longest
/// first, until the turn back keeps less than `below` of the misreading's 3D support (as where
/// another part's or a shadow's edges lie along it): turned back onto the truth. Returns the
/// share the turn back kept.
fn misread_on_lines_of_its_own_is_turned_back(below: f64) -> f64 {
    let (wedge, left, right, truth, right_from_cam) = wedge_on_table();
    let (left_edges, _) = model_edges(&wedge, &truth, &left);
    let (right_edges, _) = model_edges(&wedge, &(right_from_cam * truth), &right);
    let ev = ImageEvidence::new(&left, &left_edges, Vec::new())
        .with_right(RightImage { ev: ImageEvidence::new(&right, &right_edges, Vec::new()), right_from_cam });
    let misread = truth * crate::matcher::turns::of(&wedge)[3];
    let p = MatchParams::default();
    // The misreading's lines that the truth has none of beside them, longest first.
    let mut own: Vec<Seg> = true_lines(&wedge, &misread)
        .into_iter()
        .filter(|l| support_at(&wedge, &truth, std::slice::from_ref(l), &p).0 < 1e-6)
        .collect();
    own.sort_by(|a, b| (b.b - b.a).norm().total_cmp(&(a.b - a.a).norm()));
    // The true wedge's lines that the misreading lies along too.
    let mut lines = lines_along(&wedge, &misread, true_lines(&wedge, &truth), &p);
    let kept_share =
        |lines: &[Seg]| support_at(&wedge, &truth, lines, &p).0 / support_at(&wedge, &misread, lines, &p).0;
    for l in own {
        if kept_share(&lines) < below {
            break;
        }
        lines.push(l);
    }
    assert_turned_back(&wedge, (&lines, &p), &ev, (misread, truth));
    kept_share(&lines)
}

/// Where the 3D lines favour the misreading a little (one line of its own), the turn back
/// keeps less than all its 3D support, and is taken because both images show the true
/// wedge's own edges, where the readings lie apart, and none of the misreading's.
#[test]
fn a_wedge_misread_on_lines_that_favour_it_is_turned_where_the_images_show_its_ends() {
    let kept = misread_on_lines_of_its_own_is_turned_back(TURN_KEEP_SUPPORT);
    assert!((APART_KEEP_SUPPORT..TURN_KEEP_SUPPORT).contains(&kept), "the turn back keeps {kept:.3}");
}

/// Where they favour it more, the turn back keeps under [`APART_KEEP_SUPPORT`] of its 3D
/// support, too little for the other rules, and is taken because both images show it clearly
/// more sharply ([`CLEAR_GAIN`]).
#[test]
fn a_wedge_misread_on_lines_of_its_own_is_turned_where_both_images_show_the_truth_sharper() {
    let kept = misread_on_lines_of_its_own_is_turned_back(APART_KEEP_SUPPORT);
    assert!((CLEAR_KEEP_SUPPORT..APART_KEEP_SUPPORT).contains(&kept), "the turn back keeps {kept:.3}");
}

/// A wedge standing on its tall end, read end for end on its slope: the left image shows
/// both readings' edges (as where a neighbour's edges run along the misreading's), the
/// right only the truth's, and the slope's lines are all the 3D evidence. The turn back,
/// about the box's centre projected on the slope (1.4 mm from the slope's middle, about
/// which the misreading lies), starts off the left image's edgels, short of the image's
/// bars for a refit; it keeps enough of the 3D support to be refitted, and is taken.
#[test]
fn a_wedge_on_its_end_read_end_for_end_on_its_slope_is_turned_back() {
    let wedge = model("wedge");
    let (left, right) = pair();
    let standing = Isometry3::from_parts(
        Translation3::new(0.01, 0.02, 0.035),
        UnitQuaternion::from_euler_angles(0.0, 0.0, 0.5) * UnitQuaternion::from_euler_angles(0.0, -FRAC_PI_2, 0.0),
    );
    let truth = left.cam_from_world() * standing;
    let right_from_cam = right.cam_from_world() * left.world_from_cam;
    let slope_middle = Vector3::new(0.0, 0.0, 0.0065);
    let about_middle = Translation3::from(slope_middle)
        * UnitQuaternion::from_axis_angle(&Unit::new_normalize(Vector3::new(27.0, 0.0, 70.0)), PI)
        * Translation3::from(-slope_middle);
    let misread = truth * about_middle;
    let (mut left_edges, _) = model_edges(&wedge, &truth, &left);
    let (misread_edges, _) = model_edges(&wedge, &misread, &left);
    for (e, &pixel) in misread_edges.edgels.iter().zip(&misread_edges.pixel) {
        if left_edges.edgel_at(pixel as usize % 512, pixel as usize / 512).is_none() {
            left_edges.push(pixel as usize, *e);
        }
    }
    let (right_edges, _) = model_edges(&wedge, &(right_from_cam * truth), &right);
    let ev = ImageEvidence::new(&left, &left_edges, Vec::new())
        .with_right(RightImage { ev: ImageEvidence::new(&right, &right_edges, Vec::new()), right_from_cam });
    let p = MatchParams::default();
    let slope_lines = lines_along(&wedge, &misread, true_lines(&wedge, &truth), &p);
    let start = misread * crate::matcher::turns::of(&wedge)[4];
    let image_support = |pose: &Isometry3<f64>| crate::matcher::verify::image_support(&wedge, pose, &ev);
    let (now, then) = (image_support(&misread), image_support(&start));
    assert!(then < now - APART_START_SLACK, "the turn starts on {then:.2} of the edgels against {now:.2}");
    let support = |pose: &Isometry3<f64>| support_at(&wedge, pose, &slope_lines, &p).0;
    let kept_share = support(&start) / support(&misread);
    assert!(kept_share >= APART_START_SUPPORT, "it keeps {kept_share:.2} of the 3D support");
    assert_turned_back(&wedge, (&slope_lines, &p), &ev, (misread, truth));
}

/// A wedge lying on its bottom, read with bottom and slope swapped, where both images show
/// both readings alike and the 3D lines are those the two share: the images tie, but the
/// reading sinks into the table and the turn back rests on it. Three blocks on the table
/// beside it give the scene's level. (The reading here, the truth turned, sinks 19 mm; the
/// looks' refits on the tuning seeds sank 1.7-2.1 mm.) Without the table the reading stands.
#[test]
fn a_wedge_read_sunk_in_the_table_is_turned_where_the_images_tie() {
    let (wedge, left, right, table, truth, right_from_cam) = wedge_resting_on_table();
    let misread = truth * crate::matcher::turns::of(&wedge)[4];
    assert!(super::super::table::lowest_height(&table, &wedge, &truth).abs() < 1e-9);
    let sinks = super::super::table::lowest_height(&table, &wedge, &misread);
    assert!(sinks < -SUNK_M, "the misreading sinks {:.2} mm", sinks * 1e3);
    let edges_of_both = |cam: &mesh::PinholeCamera, from_left: &Isometry3<f64>| {
        let (mut edges, _) = model_edges(&wedge, &(from_left * truth), cam);
        let (other, _) = model_edges(&wedge, &(from_left * misread), cam);
        for (e, &pixel) in other.edgels.iter().zip(&other.pixel) {
            if edges.edgel_at(pixel as usize % 512, pixel as usize / 512).is_none() {
                edges.push(pixel as usize, *e);
            }
        }
        edges
    };
    let (left_edges, right_edges) =
        (edges_of_both(&left, &Isometry3::identity()), edges_of_both(&right, &right_from_cam));
    let ev = ImageEvidence::new(&left, &left_edges, Vec::new())
        .with_right(RightImage { ev: ImageEvidence::new(&right, &right_edges, Vec::new()), right_from_cam });
    let turned = |p: &MatchParams| {
        let lines = lines_along(&wedge, &misread, true_lines(&wedge, &truth), p);
        turned_among_blocks(&wedge, &left, (&lines, p), &ev, misread)
    };
    let on_table = MatchParams { table: Some(table), ..MatchParams::default() };
    let (was_turned, got) = turned(&on_table);
    let (mm, deg) = off_by(&truth, &got);
    assert!(was_turned && mm < 0.1 && deg < 0.1, "turned to {mm:.3} mm, {deg:.3} deg off the truth");
    let (was_turned, got) = turned(&MatchParams::default());
    assert!(!was_turned && off_by(&misread, &got).1 < 0.1, "without the table the images alone turned it");
}

/// What may hide a wedge from a camera besides its own bulk: a block between the camera and
/// the wedge, not a block far to one side.
#[test]
fn a_solid_between_camera_and_report_may_hide_it() {
    let (wedge, block) = (model("wedge"), model("block"));
    let (left, _) = pair();
    let no_edgels = Default::default();
    let ev = ImageEvidence::new(&left, &no_edgels, Vec::new());
    let view = View { ev: &ev, cam_from_left: Isometry3::identity() };
    let at = |x: Point3<f64>| left.cam_from_world() * Isometry3::translation(x.x, x.y, x.z);
    let pose = at(Point3::origin());
    // Halfway to the left camera, and 0.4 m aside.
    let (between, aside) = (at(Point3::new(-0.05, -0.275, 0.225)), at(Point3::new(0.4, 0.0, 0.0)));
    let (between, aside) = (Solid::new(&block, &between), Solid::new(&block, &aside));
    let hiders = |others: &[&Solid]| hiders_in_view(&wedge, &pose, others, &view).1.len();
    assert_eq!(hiders(&[]), 0);
    assert_eq!(hiders(&[&between]), 1);
    assert_eq!(hiders(&[&aside]), 0);
    assert_eq!(hiders(&[&aside, &between]), 1);
}

/// A wedge resting on its bottom, read so, where both images show it turned onto its slope
/// (as another part's edges or a shadow can make them seem) on the 3D lines the two share:
/// with no table known the images turn it, with the table the turn would sink into it and it
/// stands.
#[test]
fn a_turn_that_would_sink_into_the_table_is_not_taken() {
    let (wedge, left, right, table, truth, right_from_cam) = wedge_resting_on_table();
    let sunk = truth * crate::matcher::turns::of(&wedge)[4];
    let sinks = super::super::table::lowest_height(&table, &wedge, &sunk);
    assert!(sinks < -SUNK_M, "the turn sinks {:.2} mm", sinks * 1e3);
    let (left_edges, _) = model_edges(&wedge, &sunk, &left);
    let (right_edges, _) = model_edges(&wedge, &(right_from_cam * sunk), &right);
    let ev = ImageEvidence::new(&left, &left_edges, Vec::new())
        .with_right(RightImage { ev: ImageEvidence::new(&right, &right_edges, Vec::new()), right_from_cam });
    let turned = |p: &MatchParams| {
        let lines = lines_along(&wedge, &sunk, true_lines(&wedge, &truth), p);
        turned_among_blocks(&wedge, &left, (&lines, p), &ev, truth)
    };
    let (was_turned, got) = turned(&MatchParams::default());
    let (mm, deg) = off_by(&sunk, &got);
    assert!(was_turned && mm < 0.1 && deg < 0.1, "with no table, turned to {mm:.3} mm, {deg:.3} deg off the turn");
    let on_table = MatchParams { table: Some(table), ..MatchParams::default() };
    assert_eq!(turned(&on_table), (false, truth), "with the table it stands");
}

/// An L-bracket lying flat before the verged pair: the bracket, its pose, the turn of its bar
/// on itself (its arm to the bar's other side), and the cameras.
struct BracketOnTable {
    bracket: MatcherModel,
    truth: Isometry3<f64>,
    bar_flip: Isometry3<f64>,
    left: mesh::PinholeCamera,
    right: mesh::PinholeCamera,
    right_from_cam: Isometry3<f64>,
}

impl BracketOnTable {
    fn new() -> BracketOnTable {
        let (bracket, (left, right)) = (model("l_bracket"), pair());
        let truth = left.cam_from_world()
            * Isometry3::from_parts(
                Translation3::new(0.01, 0.02, 0.0125),
                UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7),
            );
        let right_from_cam = right.cam_from_world() * left.world_from_cam;
        let bar_flip = Isometry3::from_parts(
            Translation3::new(0.0, -0.035, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), PI),
        );
        BracketOnTable { bracket, truth, bar_flip, left, right, right_from_cam }
    }

    /// `lines` and both images of the bracket as it lies: turned back to it from `misread`?
    fn assert_turned_back(&self, (lines, p): (&[Seg], &MatchParams), misread: Isometry3<f64>) {
        let (left_edges, right_edges) = self.drawn(&[self.truth]);
        let right = RightImage {
            ev: ImageEvidence::new(&self.right, &right_edges, Vec::new()),
            right_from_cam: self.right_from_cam,
        };
        let ev = ImageEvidence::new(&self.left, &left_edges, Vec::new()).with_right(right);
        assert_turned_back(&self.bracket, (lines, p), &ev, (misread, self.truth));
    }

    /// The left and right images' edgels of the bracket at each of `poses` (the left camera's
    /// frame).
    fn drawn(&self, poses: &[Isometry3<f64>]) -> (EdgeMap, EdgeMap) {
        let draw = |cam: &mesh::PinholeCamera, cam_from_left: &Isometry3<f64>| {
            let mut edges = EdgeMap::new(512, 512);
            for pose in poses {
                let (more, _) = model_edges(&self.bracket, &(cam_from_left * pose), cam);
                for (e, &px) in more.edgels.iter().zip(&more.pixel) {
                    if edges.at_pixel[px as usize] == crate::front_end::canny::NO_EDGEL {
                        edges.push(px as usize, *e);
                    }
                }
            }
            edges
        };
        (draw(&self.left, &Isometry3::identity()), draw(&self.right, &self.right_from_cam))
    }
}

/// An L-bracket lying flat, read with its arm on its bar's other side (its bar turned half
/// round on itself, on the bar's 3D lines alone: the arm gave none): turned back where both
/// images show the arm where it is. The turn is one only the turn in stereo tries.
#[test]
fn an_l_bracket_read_with_its_arm_on_the_wrong_side_is_turned_back_by_both_images() {
    let f = BracketOnTable::new();
    let same = |t: &Isometry3<f64>| crate::matcher::turns::same_motion(t, &f.bar_flip);
    assert!(!crate::matcher::turns::of(&f.bracket).iter().any(same), "not among the looks' turns");
    let (misread, p) = (f.truth * f.bar_flip, MatchParams::default());
    let lines = lines_along(&f.bracket, &misread, true_lines(&f.bracket, &f.truth), &p);
    f.assert_turned_back((&lines, &p), misread);
}

/// The bracket read with its arm on the wrong side along a neighbour's edges there (3D lines
/// under the misread arm's edges that lie off the bracket), so that turned back it keeps
/// between [`FAR_KEEP_SUPPORT`] and [`CLEAR_KEEP_SUPPORT`] of the report's 3D support: turned
/// all the same, both images showing it far more sharply ([`FAR_GAIN`]).
#[test]
fn a_turn_far_sharper_in_both_images_is_taken_off_a_neighbours_lines() {
    let f = BracketOnTable::new();
    let (misread, p) = (f.truth * f.bar_flip, MatchParams::default());
    let support = |pose: &Isometry3<f64>, lines: &[Seg]| support_at(&f.bracket, pose, lines, &p).0;
    let mut lines = lines_along(&f.bracket, &misread, true_lines(&f.bracket, &f.truth), &p);
    let off_the_bracket = true_lines(&f.bracket, &misread)
        .into_iter()
        .filter(|l| support(&f.truth, std::slice::from_ref(l)) < 0.1 * (l.b - l.a).norm());
    for l in off_the_bracket {
        lines.push(l);
        if support(&f.truth, &lines) < CLEAR_KEEP_SUPPORT * support(&misread, &lines) {
            break;
        }
    }
    let kept = support(&f.truth, &lines) / support(&misread, &lines);
    assert!((FAR_KEEP_SUPPORT..CLEAR_KEEP_SUPPORT).contains(&kept), "turned back, it keeps {kept:.2} of the support");
    f.assert_turned_back((&lines, &p), misread);
}

/// A bracket read where it lies is in doubt only where both images show a turn of it as well:
/// alone before the cameras, not; with a neighbour's edges and 3D lines where the bracket's arm
/// on its bar's other side would lie, so, the turn being that one.
#[test]
fn a_reading_is_in_doubt_only_where_both_images_show_a_turn_of_it_as_well() {
    let f = BracketOnTable::new();
    let (p, flipped) = (MatchParams::default(), f.truth * f.bar_flip);
    let alike = |lines: &[Seg], drawn: &[Isometry3<f64>], asked: bool| {
        let (left_edges, right_edges) = f.drawn(drawn);
        let right =
            RightImage { ev: ImageEvidence::new(&f.right, &right_edges, Vec::new()), right_from_cam: f.right_from_cam };
        let ev = ImageEvidence::new(&f.left, &left_edges, Vec::new()).with_right(right);
        let located = [report(&f.bracket, f.truth)];
        doubt::turned_alike(std::slice::from_ref(&f.bracket), (lines, &p), &ev, &located, &[asked]).remove(0)
    };
    let alone = alike(&true_lines(&f.bracket, &f.truth), &[f.truth], true);
    assert!(alone.is_none(), "alone: {alone:?}");
    let lines = [true_lines(&f.bracket, &f.truth), true_lines(&f.bracket, &flipped)].concat();
    let both = alike(&lines, &[f.truth, flipped], true).expect("a turn that fits as well");
    let (mm, deg) = off_by(&flipped, &both.cam_from_model);
    assert!(mm < 0.5 && deg < 0.5, "{both:?}: {mm:.2} mm, {deg:.2} deg from the turn");
    assert!(alike(&lines, &[f.truth, flipped], false).is_none(), "not asked");
}

/// A turn fits as well as the report where the two tie in both images, or where either image
/// shows the turn more (the images disagree); not where it keeps too little of the 3D support.
#[test]
fn a_turn_fits_as_well_where_it_ties_or_either_image_shows_it_more() {
    let fits = |report_shown: [f64; 2], turn_shown: [f64; 2], support_kept: f64| {
        let t = doubt::TurnedAlike { cam_from_model: Isometry3::identity(), report_shown, turn_shown, support_kept };
        t.fits_as_well()
    };
    assert!(fits([0.8, 0.8], [0.75, 0.78], 1.0), "ties");
    assert!(fits([0.83, 1.0], [0.88, 0.83], 1.0), "the images disagree");
    assert!(!fits([0.83, 1.0], [0.84, 0.83], 1.0), "the left image shows the turn more by too little");
    assert!(!fits([0.8, 0.8], [0.6, 0.8], 1.0), "the left image shows the turn less");
    assert!(!fits([0.8, 0.8], [0.9, 0.9], 0.7), "sharper, on too little of the 3D lines");
}
