//! The table as `marvin run` knows it, for `marvin locate WORLD` and `marvin eval locate`: the
//! hand-eye transform (from a file, or calibrated now through the cameras vision sees by) and the
//! table's height in the robot's base frame, which the cell's layout gives the server. Never the
//! true camera pose: vision is judged on the table it would have in a run.

use super::calibrate::Cell;
use super::session::{HandEye, hand_eye};
use nalgebra::{Isometry3, Point3};
use std::path::Path;

/// The table as the matcher is given it, and where that came from.
pub struct TableEstimate {
    /// Where the table's top lies in the left camera's frame (a frame whose plane z = 0 is the
    /// top, z up); `None` when nothing places it (the matcher then looks without a table).
    pub cam_from_table: Option<Isometry3<f64>>,
    /// Where it came from, or why there is none (for the reports).
    pub source: String,
}

/// The table by `hand_eye_file`'s transform, or (without one) by a calibration made on `seed`'s
/// scene first. A world with no arm, or a calibration that fails (through cameras that cannot
/// see the flag, say), leaves the matcher without a table, and says so: a hand-eye file from
/// another source never fails silently, its errors are returned.
pub fn cam_from_table(
    world: &Path,
    scn: &sim::Scenario,
    cameras: &mesh::StereoCalibration,
    hand_eye_file: Option<&Path>,
    seed: u64,
    quiet: bool,
) -> anyhow::Result<TableEstimate> {
    let none = |why: String| {
        if !quiet {
            eprintln!("warning: {why}: the matcher looks without a table");
        }
        Ok(TableEstimate { cam_from_table: None, source: format!("none: {why}") })
    };
    let Some(robot) = scn.world.robot.as_ref() else {
        return none(format!("{}: no arm, so no hand-eye transform to place the table by", world.display()));
    };
    // The world's origin is the centre of the table's top (as the server says in `hello`).
    let table_top_base_m = (robot.world_from_base().inverse() * Point3::origin()).z;
    let (cam_from_base, source) = match hand_eye_file {
        Some(f) => {
            (hand_eye::HandEyeFile::load(f)?.cam_from_base.to_isometry(), format!("hand-eye file {}", f.display()))
        }
        None => match calibrated(world, scn, cameras, seed, quiet) {
            Ok(x) => (x, format!("hand-eye calibration on seed {seed}'s scene")),
            Err(e) => return none(format!("the hand-eye calibration failed ({e:#})")),
        },
    };
    let cam_from_table = Some(cam_from_base * Isometry3::translation(0.0, 0.0, table_top_base_m));
    Ok(TableEstimate { cam_from_table, source })
}

/// A hand-eye calibration on `seed`'s scene through `cameras`, as `marvin run` makes it.
fn calibrated(
    world: &Path,
    scn: &sim::Scenario,
    cameras: &mesh::StereoCalibration,
    seed: u64,
    quiet: bool,
) -> anyhow::Result<Isometry3<f64>> {
    if !quiet {
        eprintln!(
            "calibrating the hand-eye transform on seed {seed}'s scene, which places the table as `marvin run` \
             places it (--hand-eye FILE skips this) ..."
        );
    }
    let cell = Cell::start(world, seed, None)?;
    let (mut client, _) = cell.connect_greeted()?;
    // Perception reads the flag in the left camera's frame.
    let cameras = cameras.in_left_frame();
    let (cam_from_base, _) = hand_eye(&mut client, &scn.library, &HandEye::Calibrate, seed, quiet, &cameras)?;
    client.bye()?;
    cell.stop()?;
    Ok(cam_from_base)
}
