//! The table the parts rest on: a reading that puts a part through its top is no reading.
//!
//! A flat part turned over (a wedge end for end, an L-bracket face down) can run along the
//! same few 3D lines and image edges as the part itself, and a part read onto another's lines
//! can lie at any angle; many such readings leave the part half sunk in the table, which no
//! part in the cell can be. Where the cell's layout is known (the run has it from the robot
//! server, as the table's height in `base`, and the hand-eye calibration; evaluation from the
//! rig's calibration against the table), the matcher refuses them: in the search, so that the
//! next hypothesis is verified in their place, in the merge, and when a report is read again
//! turned over or as another model.
//!
//! Chosen on tuning seeds (`marvin locate --json`, `widgets.toml`, `dense.toml` and
//! `side_light.toml` 1-60, and the false reports of `widgets.toml` 1-500): of 1532 right
//! reports the lowest corner lay at most 4.1 mm under the table top (poses a degree or two off
//! on a part 60 mm long, and parts settled a little into it); of the 18 false reports on
//! `widgets.toml` 1-500, six lay 17-40 mm under it and three 2-6 mm.

use super::model::{Located, MatcherModel, Table};
use nalgebra::{Isometry3, Matrix3, Rotation3, Vector3};

/// How far (metres) a reading's lowest corner may lie under the table top: see the module's
/// figures. Right readings came within 4.1 mm; this leaves them room.
pub const MAX_BELOW_M: f64 = 0.006;

/// Whether `model` at `pose` (`cam_from_model`) has a corner more than [`MAX_BELOW_M`] under
/// the top of `table`.
pub fn cuts(table: &Table, model: &MatcherModel, pose: &Isometry3<f64>) -> bool {
    model.corners.iter().any(|corner| table.height_of(&(pose * corner)) < -MAX_BELOW_M)
}

/// Whether a reading of `model` at `pose` is refused for cutting into the table, if one is known.
pub(crate) fn through_table(table: Option<&Table>, model: &MatcherModel, pose: &Isometry3<f64>) -> bool {
    table.is_some_and(|t| cuts(t, model, pose))
}

/// Whether `model` at `pose` lies nearly flat on `table`: one of its resting faces turned
/// down within [`FLAT_TILT_DEG`] and its lowest corner within [`FLAT_NEAR_M`] of the top. (A
/// pose from two short 3D lines is a few degrees and millimetres off.)
pub(crate) fn nearly_flat(table: &Table, model: &MatcherModel, pose: &Isometry3<f64>) -> bool {
    a_resting_face_down(table, model, pose) && lowest_height(table, model, pose).abs() <= FLAT_NEAR_M
}

/// Whether one of `model`'s resting faces is turned down within [`FLAT_TILT_DEG`] at `pose`.
fn a_resting_face_down(table: &Table, model: &MatcherModel, pose: &Isometry3<f64>) -> bool {
    let down = pose.rotation.inverse_transform_vector(&-Vector3::from(table.up));
    let cos = FLAT_TILT_DEG.to_radians().cos();
    model.resting.iter().any(|n| n.dot(&down) >= cos)
}

/// How high `model`'s lowest corner lies above the top of `table` with the model at `pose`
/// (metres, negative under it). The lowest corner is the one furthest along `down` in the
/// model's frame: no corner need be carried into `cam` (this runs for every hypothesis of the
/// first look).
pub(crate) fn lowest_height(table: &Table, model: &MatcherModel, pose: &Isometry3<f64>) -> f64 {
    let up = Vector3::from(table.up);
    let down = pose.rotation.inverse_transform_vector(&-up);
    let deepest = model.corners.iter().map(|c| down.dot(&c.coords)).fold(f64::MIN, f64::max);
    up.dot(&pose.translation.vector) + table.camera_height_m - deepest
}

/// The scene's reports' lowest corners (metres above `table`'s top, median) where they lie
/// within [`NEAR_TOP_M`] of it, if [`MIN_RESTING`] do: the top as the parts find it. The
/// table the hand-eye calibration places may lie a millimetre off (the ideal cell's fixture:
/// +1.04 mm, docs/TUNING.md "Dense false reports: sunk readings..."); the parts on it do not.
pub(crate) fn resting_level(models: &[MatcherModel], kept: &[Located], table: &Table) -> Option<f64> {
    let mut heights: Vec<f64> = kept
        .iter()
        .filter_map(|r| {
            let model = models.iter().find(|m| m.name == r.model)?;
            Some(lowest_height(table, model, &r.cam_from_model))
        })
        .filter(|h| h.abs() <= NEAR_TOP_M)
        .collect();
    heights.sort_by(f64::total_cmp);
    (heights.len() >= MIN_RESTING).then(|| heights[heights.len() / 2])
}

/// See [`resting_level`], metres and reports.
const NEAR_TOP_M: f64 = 0.004;
const MIN_RESTING: usize = 3;

/// The least turn taking unit vector `from` onto unit vector `to` (Rodrigues' formula, with
/// the cosine and sine of the angle their dot and cross products give). Why not nalgebra's
/// `Rotation3::rotation_between`: it takes the angle's inverse cosine, which for directions
/// within rounding of each other (a part laid flat and laid flat again, [`super::table_look::laid_flat`])
/// is ill-conditioned (a turn of 1e-8 rad for none) or, for a cosine a hair over 1, NaN. Near
/// opposite, where the axis is ill-defined, nalgebra's turn, or half a turn about an axis
/// across `from` where it gives none.
pub(crate) fn turn_between(from: &Vector3<f64>, to: &Vector3<f64>) -> Rotation3<f64> {
    let (cross, cos) = (from.cross(to), from.dot(to));
    if 1.0 + cos < 1e-6 {
        let across = from.cross(&if from.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() });
        return Rotation3::rotation_between(from, to).unwrap_or_else(|| {
            Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(across), std::f64::consts::PI)
        });
    }
    let k = cross.cross_matrix();
    Rotation3::from_matrix_unchecked(Matrix3::identity() + k + k * k / (1.0 + cos))
}

/// Whether a hypothesis of `model` at `pose` lies so deep in the table ([`HYPOTHESIS_BELOW_M`])
/// that no refinement could bring it out: it is not worth counting its support.
pub(crate) fn hopelessly_sunk(table: Option<&Table>, model: &MatcherModel, pose: &Isometry3<f64>) -> bool {
    table.is_some_and(|t| lowest_height(t, model, pose) < -HYPOTHESIS_BELOW_M)
}

/// See [`hopelessly_sunk`], metres: two and a half times [`MAX_BELOW_M`]. A third of the first
/// look's hypotheses on the bench scene lay deeper (their support no longer counted), and a
/// reading that deep takes a place among the best at its place from one that may be right. On
/// the tuning seeds (`marvin eval locate`, `widgets.toml` 1-500, `dense.toml` and
/// `side_light.toml` 1-200) 15 mm found 0 / 5 / 2 objects more with 0 / 1 / 0 false reports
/// fewer; 8 mm 2 / 9 / 2 more objects, but 1 more false report in `dense.toml`.
pub(crate) const HYPOTHESIS_BELOW_M: f64 = 0.015;

/// Whether `model` at `pose` lies flat ([`FLAT_TILT_DEG`]) with its lowest corner
/// [`FLOATS_M`] to [`FLOATS_MAX_M`] above `level` (a height above `table`'s top): held up by
/// nothing, as no library part is thinner than 25 mm.
pub(crate) fn floats_flat((table, level): (&Table, f64), model: &MatcherModel, pose: &Isometry3<f64>) -> bool {
    let height = lowest_height(table, model, pose) - level;
    (FLOATS_M..=FLOATS_MAX_M).contains(&height) && a_resting_face_down(table, model, pose)
}

/// The reports of `kept` that lie flat above the scene's [`resting_level`] ([`floats_flat`])
/// dropped: what holds them up is not there, and a turn that rests was not taken. So are those
/// still sunk [`SUNK_DEEP_M`] under it: the polish could not hold them on the table
/// (`polish::lift_sunk`) and no turn of theirs rests, and no part lies in the table.
pub(crate) fn drop_floating_or_sunk(models: &[MatcherModel], table: &Table, kept: &mut Vec<Located>) {
    let Some(level) = resting_level(models, kept, table) else { return };
    kept.retain(|r| {
        models.iter().find(|m| m.name == r.model).is_none_or(|m| {
            let pose = &r.cam_from_model;
            !floats_flat((table, level), m, pose) && lowest_height(table, m, pose) >= level - SUNK_DEEP_M
        })
    });
}

/// See [`drop_floating_or_sunk`], metres under the scene's [`resting_level`]: twice what the
/// turns and the polish take for sunk (`polish::SUNK_M`). The right reports' lowest corners lie
/// within 0.7 mm of the level (docs/TUNING.md, "Dense false reports: sunk readings..."). On
/// realistic `dense.toml` tuning seeds 5001-5400 through tuning seed 1's calibrations, 8 of 5315
/// reports ended more than 1.5 mm under the level: the five deeper than 2.5 mm (3.9-6.1 mm) were
/// four false reports (wedges with bottom and slope swapped, a wedge on a widget, an L-bracket
/// on a U-channel) and one that the overlap check drops anyway; of the three at 1.7-2.0 mm one
/// was false and one right. `marvin eval locate` (located, false reports): 0.9250 / 63 -> 0.9250
/// / 59 with 2.5 or 3 mm, 0.9248 / 58 with 1.5 mm.
pub(crate) const SUNK_DEEP_M: f64 = 0.003;

/// See [`floats_flat`], metres: as far above the level as a sunk reading lies under it
/// (`polish::SUNK_M`). On realistic `dense.toml` tuning seeds 1-400 and `widgets.toml` 1-300,
/// through tuning seed 1's calibrations, of the reports lying flat above the level (their three
/// lowest corners within 2.5 mm), the one right one lay 1.2 mm above it; five false ones
/// 2.2-7.7 mm (two wedges read with bottom and slope swapped, 2.2 and 2.3 mm; two hexagonal
/// prisms read on a block). Such a report has its turns refitted as a sunk one has
/// (`polish::turn_in_stereo`), and is dropped if it still floats. `marvin eval locate` (located,
/// false reports), before and after: realistic `dense.toml` 61-200 91.09% / 16 -> 91.09% / 13,
/// `widgets.toml` 701-1100 98.41% / 14 -> 98.41% / 13; ideal `dense.toml` 1-160 94.01% / 20 ->
/// 93.97% / 19 (seed 12's wedge, right within 10 mm and 5 deg, lay flat 4 mm above the table);
/// realistic `dense.toml` 1-60, `widgets.toml` 1-300 and 301-700, ideal `widgets.toml` 1-100
/// the same.
pub(crate) const FLOATS_M: f64 = 0.0015;
/// See [`floats_flat`], metres: a part lying flat on another lies 25 mm or more up.
pub(crate) const FLOATS_MAX_M: f64 = 0.012;

/// See [`nearly_flat`].
pub(crate) const FLAT_TILT_DEG: f64 = 8.0;
/// See [`nearly_flat`], metres.
pub(crate) const FLAT_NEAR_M: f64 = 0.01;

/// Whether `model` at `pose` rests flat on `table`: three corners not on one line lie within
/// `within` (metres) of its top.
pub(crate) fn rests_flat(table: &Table, model: &MatcherModel, pose: &Isometry3<f64>, within: f64) -> bool {
    let on: Vec<&nalgebra::Point3<f64>> =
        model.corners.iter().filter(|c| table.height_of(&(pose * *c)).abs() <= within).collect();
    let spans = |a: &&nalgebra::Point3<f64>, b: &&nalgebra::Point3<f64>, c: &&nalgebra::Point3<f64>| {
        (*b - *a).cross(&(*c - *a)).norm() > 1e-4
    };
    on.iter()
        .enumerate()
        .any(|(i, a)| on[i + 1..].iter().enumerate().any(|(k, b)| on[i + k + 2..].iter().any(|c| spans(a, b, c))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::matcher::fixtures::model;
    use crate::matcher::model::MatchParams;
    use nalgebra::{Point3, Translation3, UnitQuaternion};

    /// A camera 0.6 m above the table looking down at it, tilted: `cam_from_table`.
    fn cam_from_table() -> Isometry3<f64> {
        let table_from_cam =
            Isometry3::from_parts(Translation3::new(0.1, -0.5, 0.6), UnitQuaternion::from_euler_angles(-2.3, 0.1, 0.2));
        table_from_cam.inverse()
    }

    /// Heights measured in the table's own frame agree with the plane's, on and off the top.
    /// The least turn takes each axis onto itself (no turn) and onto its opposite (half a turn
    /// about an axis across it, where the axis of the turn is anyone's guess).
    #[test]
    fn turns_between_an_axis_and_itself_or_its_opposite() {
        for axis in [Vector3::x(), Vector3::y(), Vector3::z()] {
            assert!((turn_between(&axis, &axis).matrix() - Matrix3::identity()).norm() < 1e-15, "{axis}");
            assert!((turn_between(&axis, &-axis) * axis + axis).norm() < 1e-12, "{axis} not turned over");
        }
    }

    #[test]
    fn heights_are_measured_from_the_top() {
        let cam_from_table = cam_from_table();
        let table = Table::from_cam_from_table(&cam_from_table);
        for (x, y, z) in [(0.0, 0.0, 0.0), (0.2, -0.1, 0.03), (-0.3, 0.4, -0.02)] {
            let in_cam = cam_from_table * Point3::new(x, y, z);
            assert!((table.height_of(&in_cam) - z).abs() < 1e-12, "{x} {y} {z}: {}", table.height_of(&in_cam));
        }
        assert!((table.height_of(&Point3::origin()) - 0.6).abs() < 1e-12, "the camera is 0.6 m up");
    }

    /// A wedge lying flat on its slope 3 mm above the table floats; on the table, lying on
    /// another part 30 mm up, or leaning 30 degrees with its lowest corner 3 mm up, it does
    /// not. Among three blocks on the table, the floating wedge is dropped and they are not.
    #[test]
    fn a_part_lying_flat_on_nothing_floats_and_is_dropped() {
        let (wedge, block) = (model("wedge"), model("block"));
        let cam_from_table = cam_from_table();
        let table = Table::from_cam_from_table(&cam_from_table);
        let slope = *wedge.resting.iter().find(|n| n.z.abs() < 0.9).expect("a sloping face");
        let on_slope = turn_between(&slope, &-Vector3::z());
        let at = |m: &MatcherModel, turn: Rotation3<f64>, height: f64| {
            let lowest = m.corners.iter().map(|c| (turn * c).z).fold(f64::MAX, f64::min);
            let q = UnitQuaternion::from_rotation_matrix(&turn);
            cam_from_table * Isometry3::from_parts(Translation3::new(0.03, -0.02, height - lowest), q)
        };
        let floats = |pose: &Isometry3<f64>| floats_flat((&table, 0.0), &wedge, pose);
        assert!(floats(&at(&wedge, on_slope, 0.003)), "flat, 3 mm up");
        assert!(!floats(&at(&wedge, on_slope, 0.0)), "on the table");
        assert!(!floats(&at(&wedge, on_slope, 0.03)), "on another part");
        let leaning = Rotation3::from_axis_angle(&Vector3::x_axis(), 30f64.to_radians()) * on_slope;
        assert!(!floats(&at(&wedge, leaning, 0.003)), "leaning");
        let report = crate::matcher::fixtures::report;
        let flat = Rotation3::identity();
        let mut kept = vec![
            report(&block, at(&block, flat, 0.0004)),
            report(&wedge, at(&wedge, on_slope, 0.003)),
            report(&block, at(&block, flat, 0.0002)),
            report(&block, at(&block, flat, 0.0003)),
        ];
        drop_floating_or_sunk(&[wedge.clone(), block.clone()], &table, &mut kept);
        let names: Vec<&str> = kept.iter().map(|r| r.model.as_str()).collect();
        assert_eq!(names, ["block", "block", "block"]);
    }

    /// Among blocks resting 0.2-0.4 mm above the table, a wedge 2 mm under their level stands
    /// (a pose a little off) and one 4 mm under it is dropped; so is a block 4 mm under it.
    #[test]
    fn a_part_deep_in_the_table_is_dropped() {
        let (wedge, block) = (model("wedge"), model("block"));
        let cam_from_table = cam_from_table();
        let table = Table::from_cam_from_table(&cam_from_table);
        let at = |m: &MatcherModel, x: f64, height: f64| {
            let lowest = m.corners.iter().map(|c| c.z).fold(f64::MAX, f64::min);
            cam_from_table * Isometry3::translation(x, 0.0, height - lowest)
        };
        let report = crate::matcher::fixtures::report;
        let mut kept = vec![
            report(&block, at(&block, 0.0, 0.0004)),
            report(&wedge, at(&wedge, 0.1, -0.0017)),
            report(&block, at(&block, 0.2, 0.0002)),
            report(&wedge, at(&wedge, 0.3, -0.0037)),
            report(&block, at(&block, 0.4, 0.0003)),
            report(&block, at(&block, 0.5, -0.0037)),
        ];
        let level = resting_level(&[wedge.clone(), block.clone()], &kept, &table).expect("parts on the table");
        assert!((level - 0.0002).abs() < 1e-9, "the level is the reports' median: {level}");
        drop_floating_or_sunk(&[wedge.clone(), block.clone()], &table, &mut kept);
        let names: Vec<&str> = kept.iter().map(|r| r.model.as_str()).collect();
        assert_eq!(names, ["block", "wedge", "block", "block"]);
        let xs: Vec<f64> = kept.iter().map(|r| (cam_from_table.inverse() * r.cam_from_model).translation.x).collect();
        assert_eq!(xs.iter().map(|x| (x * 10.0).round() as i32).collect::<Vec<_>>(), [0, 1, 2, 4]);
    }

    /// A block resting on the table passes, the same block sunk 1 cm into it is refused, and
    /// one lifted above it passes (parts lean on others).
    #[test]
    fn a_part_through_the_top_is_refused() {
        let block = model("block");
        let cam_from_table = cam_from_table();
        let table = Table::from_cam_from_table(&cam_from_table);
        let lowest = block.lines.iter().flat_map(|l| [l.a.z, l.b.z]).fold(f64::MAX, f64::min);
        let at = |z: f64| {
            cam_from_table
                * Isometry3::from_parts(
                    Translation3::new(0.05, 0.02, z - lowest),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.7),
                )
        };
        assert!(!cuts(&table, &block, &at(0.0)), "resting on the top");
        assert!(!cuts(&table, &block, &at(-0.004)), "within the slack");
        assert!(cuts(&table, &block, &at(-0.010)), "sunk 10 mm");
        assert!(!cuts(&table, &block, &at(0.05)), "lifted");
        assert!(!through_table(None, &block, &at(-0.010)), "no table known, nothing refused");
    }

    /// The lowest corner's height, worked out in the model's frame, is the least of the corners'
    /// heights carried into `cam`, at any tilt; a hypothesis is given up only well under the
    /// top, past where a refused reading lies.
    #[test]
    fn a_hypothesis_is_given_up_only_deep_in_the_table() {
        let wedge = model("wedge");
        let cam_from_table = cam_from_table();
        let table = Table::from_cam_from_table(&cam_from_table);
        for (tilt, z) in [(0.0, 0.0), (0.7, -0.01), (1.9, 0.03), (2.6, -0.02)] {
            let turn = UnitQuaternion::from_euler_angles(tilt, 0.4 * tilt, 1.1);
            let pose = cam_from_table * Isometry3::from_parts(Translation3::new(0.02, -0.01, z), turn);
            let least = wedge.corners.iter().map(|c| table.height_of(&(pose * c))).fold(f64::MAX, f64::min);
            assert!((lowest_height(&table, &wedge, &pose) - least).abs() < 1e-12, "tilt {tilt}");
        }
        let block = model("block");
        let lowest = block.corners.iter().map(|c| c.z).fold(f64::MAX, f64::min);
        let at = |z: f64| cam_from_table * Isometry3::translation(0.0, 0.0, z - lowest);
        assert!(cuts(&table, &block, &at(-0.010)) && !hopelessly_sunk(Some(&table), &block, &at(-0.010)));
        assert!(hopelessly_sunk(Some(&table), &block, &at(-0.020)), "20 mm under the top");
        assert!(!hopelessly_sunk(None, &block, &at(-0.020)), "no table known, nothing given up");
    }

    /// A wedge on each of its resting faces, turned off it by 0-14 degrees about a horizontal
    /// axis and moved 0-16 mm up or down: judged nearly flat exactly when the turn is within
    /// [`FLAT_TILT_DEG`] and its lowest corner, carried into `cam` corner by corner, within
    /// [`FLAT_NEAR_M`] of the top. And it rests flat (three corners on the top) only untilted.
    #[test]
    fn nearly_flat_agrees_with_the_corners_heights() {
        let wedge = model("wedge");
        let cam_from_table = cam_from_table();
        let table = Table::from_cam_from_table(&cam_from_table);
        let corners: Vec<Point3<f64>> = wedge.lines.iter().flat_map(|l| [l.a, l.b]).collect();
        let mut judged = [0, 0];
        for n in &wedge.resting {
            let onto = UnitQuaternion::rotation_between(n, &-nalgebra::Vector3::z())
                .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&nalgebra::Vector3::x_axis(), std::f64::consts::PI));
            for tilt_deg in [0.0f64, 4.0, 7.5, 8.5, 14.0] {
                for dz in [-0.016, -0.009, 0.0, 0.009, 0.011, 0.016] {
                    let turn = UnitQuaternion::from_euler_angles(tilt_deg.to_radians(), 0.0, 0.0) * onto;
                    let lowest = corners.iter().map(|c| (turn * c).z).fold(f64::MAX, f64::min);
                    let pose =
                        cam_from_table * Isometry3::from_parts(Translation3::new(0.03, -0.01, dz - lowest), turn);
                    let lowest_in_cam = corners.iter().map(|c| table.height_of(&(pose * c))).fold(f64::MAX, f64::min);
                    let expect = tilt_deg <= FLAT_TILT_DEG && lowest_in_cam.abs() <= FLAT_NEAR_M;
                    assert_eq!(nearly_flat(&table, &wedge, &pose), expect, "face {n:?}, {tilt_deg} deg, {dz} m");
                    judged[usize::from(expect)] += 1;
                    if dz == 0.0 {
                        assert_eq!(rests_flat(&table, &wedge, &pose, 1e-6), tilt_deg == 0.0, "{tilt_deg} deg");
                    }
                }
            }
        }
        assert!(judged[0] > 20 && judged[1] > 20, "{judged:?}");
    }

    /// The matcher finds a block from its wireframe's lines where it rests on the table; where
    /// the same lines put it 40 mm into the table (deeper than the block is tall, so no reading
    /// of them keeps clear of it), it finds it only if no table is known.
    #[test]
    fn the_search_refuses_a_reading_through_the_table() {
        let block = model("block");
        let cam_from_table = cam_from_table();
        let lowest = block.lines.iter().flat_map(|l| [l.a.z, l.b.z]).fold(f64::MAX, f64::min);
        let at = |z: f64| {
            cam_from_table
                * Isometry3::from_parts(
                    Translation3::new(0.0, 0.03, z - lowest),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.4),
                )
        };
        let lines_at = |pose: &Isometry3<f64>| block.lines.iter().map(|l| l.transformed(pose)).collect::<Vec<_>>();
        let with_table =
            MatchParams { table: Some(Table::from_cam_from_table(&cam_from_table)), ..MatchParams::default() };
        for (z, expect_with_table) in [(0.0, 1), (-0.040, 0)] {
            let scene = lines_at(&at(z));
            let found = crate::matcher::locate(&block, &scene, &with_table, None);
            assert_eq!(found.len(), expect_with_table, "{z} m, table known");
            // Where the block's middle is (a symmetric block may be found turned about it).
            let middle = block.bounding_sphere().0;
            assert!(found.iter().all(|l| (l.cam_from_model * middle - at(z) * middle).norm() < 1e-3));
            assert_eq!(
                crate::matcher::locate(&block, &scene, &MatchParams::default(), None).len(),
                1,
                "{z} m, no table"
            );
        }
    }
}
