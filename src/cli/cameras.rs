//! Where a client's cameras come from: a calibration file, the robot server's published
//! calibration, or a camera calibration from the board made now (the capture carries no camera
//! model of its own).

use anyhow::Context;
use marvin::engine::calibrate_cameras::{CameraCalibConfig, CameraCalibration, calibrate_cameras};
use marvin::engine::client::Client;
use marvin::protocol::HelloReply;

/// The cameras a run sees through: `given` (a calibration file), else the ones the server
/// publishes (a server given a calibration file), else measured now from the board, as a cell's
/// operator would before anything else. A measurement comes back with them (to record).
pub fn cameras(
    client: &mut Client,
    hello: &HelloReply,
    library: &mesh::Library,
    given: Option<&mesh::StereoCalibration>,
    seed: u64,
    quiet: bool,
    keep_images: bool,
) -> anyhow::Result<(mesh::StereoCalibration, Option<CameraCalibration>)> {
    if let Some(cameras) = given {
        return Ok((cameras.clone(), None));
    }
    if let Some(rig) = client.capture()?.calibration {
        if !quiet {
            eprintln!("the cameras as the robot server publishes them (its --cameras file)");
        }
        return Ok((marvin::engine::perception::stereo_calibration(&rig)?, None));
    }
    if !quiet {
        eprintln!("the cameras are uncalibrated: calibrating them from the board first");
    }
    let config = CameraCalibConfig { seed, ..CameraCalibConfig::default() };
    let table_top = hello.table_top_base_m.context("the robot server does not say where the table's top is")?;
    let mut progress = |line: &str| {
        if !quiet {
            eprintln!("  cameras {line}");
        }
    };
    let c = calibrate_cameras(client, table_top, library, &config, keep_images, &mut progress)
        .context("calibrating the cameras")?;
    if !quiet {
        let s = &c.solution;
        eprintln!(
            "  cameras: {} board poses used, reprojection RMS {:.3} px, baseline {:.2} mm",
            s.boards.iter().flatten().count(),
            s.rms_px,
            s.right_from_left.inverse().translation.vector.norm() * 1e3
        );
    }
    Ok((c.stereo_calibration(), Some(c)))
}
