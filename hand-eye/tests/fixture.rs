//! Calibration regression: sightings recorded from a simulated calibration (checked in) must
//! give the result recorded with them. A change to the solver that moves the answer -- by more
//! than a micrometre or a microradian -- fails here, and the fixture is then remade on purpose.

use hand_eye::{PoseJson, Sighting, SolveParams, solve};
use serde::Deserialize;

#[derive(Deserialize)]
struct Fixture {
    flag_half_extents_m: [f64; 3],
    sightings: Vec<RecordedSighting>,
    expected: Expected,
}

#[derive(Deserialize)]
struct RecordedSighting {
    base_from_gripper: PoseJson,
    cam_from_flag: PoseJson,
}

#[derive(Deserialize)]
struct Expected {
    cam_from_base: PoseJson,
    gripper_from_flag: PoseJson,
    residual_mm_rms: f64,
    used: Vec<bool>,
}

#[test]
fn recorded_sightings_reproduce_the_recorded_result() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/sightings_widgets_seed1.json");
    let f: Fixture = serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    let sightings: Vec<Sighting> = f
        .sightings
        .iter()
        .map(|s| Sighting {
            base_from_gripper: s.base_from_gripper.to_isometry(),
            cam_from_flag: s.cam_from_flag.to_isometry(),
        })
        .collect();
    let s = solve(&sightings, &SolveParams::for_box(f.flag_half_extents_m)).unwrap();
    for (got, want, name) in [
        (&s.cam_from_base, f.expected.cam_from_base.to_isometry(), "cam_from_base"),
        (&s.gripper_from_flag, f.expected.gripper_from_flag.to_isometry(), "gripper_from_flag"),
    ] {
        let dt = (got.translation.vector - want.translation.vector).norm();
        let dr = got.rotation.angle_to(&want.rotation);
        assert!(dt < 1e-6 && dr < 1e-6, "{name} moved {:.3} um, {:.3} urad", dt * 1e6, dr * 1e6);
    }
    assert!((s.residual_mm_rms - f.expected.residual_mm_rms).abs() < 1e-6);
    assert_eq!(s.used, f.expected.used);
}
