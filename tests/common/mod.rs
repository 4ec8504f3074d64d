//! What the integration tests share (`tests/batch.rs`, `tests/slurm.rs`, `tests/deploy.rs`,
//! `tests/realistic_vision.rs`): the `marvin` binary run from the repository, a scratch folder,
//! and the figures of a summary.

#![allow(dead_code)] // each test binary uses its own share of these

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The calibration the batches share: `marvin calibrate cameras worlds/ideal/widgets.toml --seed 3`,
/// then `marvin calibrate ... --cameras` through them (tuning seed 3).
pub const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/ideal_seed3");

/// An empty folder of this test's own.
pub fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The `marvin` binary, run from the repository (where the worlds are).
pub fn marvin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_marvin"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

/// `eval run` of tuning seeds 1-4 on the ideal world with the shared files, and `extra`.
pub fn eval_run(extra: &[&str]) -> Command {
    let mut c = marvin();
    c.args(["eval", "run", "worlds/ideal/widgets.toml", "--scenes", "4", "--seed", "1", "--json"])
        .args(["--cameras", &format!("{FIXTURES}/cameras.json"), "--hand-eye", &format!("{FIXTURES}/hand_eye.json")])
        .args(extra);
    c
}

/// The JSON a command printed, which must have succeeded.
pub fn ok(o: Output) -> Value {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_slice(&o.stdout).unwrap()
}

/// A summary without `keys` (wall times, which differ between any two runs) and its shard label.
pub fn without(mut v: Value, keys: &[&str]) -> Value {
    for k in keys.iter().chain(&["shard"]) {
        v.as_object_mut().unwrap().remove(*k);
    }
    v
}

/// An `eval run` summary without its wall times and its shard label.
pub fn figures(v: Value) -> Value {
    without(v, &["cycle_s_mean", "vision_cycle_ms_median"])
}
