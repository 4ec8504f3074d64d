//! A regression fixture: the corners `marvin calibrate cameras worlds/widgets.toml --seed 3`
//! found (tests/fixtures/seed3_corners.json) replayed through the solve, against the solution
//! recorded with them (seed3_cameras.json). Every parameter must come back within a
//! ten-thousandth of its own standard deviation: a change to the solve that moves the answer by
//! anything that matters fails here. (Re-record both files together, with the command above and
//! `--save-images`, when a change is meant to move it.)

use camera_calib::file::CamerasFile;
use camera_calib::{Board, Options, ViewCorners, calibrate_stereo};
use std::path::Path;

#[derive(serde::Deserialize)]
struct Fixture {
    views: Vec<ViewCorners>,
}

#[test]
fn recorded_corners_give_the_recorded_solution() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let fixture: Fixture =
        serde_json::from_str(&std::fs::read_to_string(dir.join("seed3_corners.json")).unwrap()).unwrap();
    let recorded = CamerasFile::load(&dir.join("seed3_cameras.json")).unwrap();
    let s = calibrate_stereo(&Board::LIBRARY, [recorded.width, recorded.height], &fixture.views, &Options::default())
        .unwrap();
    let now = CamerasFile::from_solution(&s, [recorded.width, recorded.height]);
    for (got, want) in [(&now.left, &recorded.left), (&now.right, &recorded.right)] {
        let (g, w) = (got.intrinsics().to_params(), want.intrinsics().to_params());
        for k in 0..9 {
            let tolerance = 1e-4 * want.sigma[k] + 1e-12;
            assert!(
                (g[k] - w[k]).abs() <= tolerance,
                "{}: {} vs recorded {}",
                camera_calib::camera::INTRINSIC_NAMES[k],
                g[k],
                w[k]
            );
        }
    }
    let (a, b) = (now.right_from_left.isometry(), recorded.right_from_left.isometry());
    let sigma = &recorded.right_from_left_sigma;
    assert!(
        (a.translation.vector - b.translation.vector).norm() <= 1e-4 * sigma[3..].iter().fold(0.0f64, |m, s| m.max(*s))
    );
    assert!(a.rotation.angle_to(&b.rotation) <= 1e-4 * sigma[..3].iter().fold(0.0f64, |m, s| m.max(*s)));
    assert!((now.rms_px - recorded.rms_px).abs() < 1e-9);
}
