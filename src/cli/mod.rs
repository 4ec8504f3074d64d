//! The command line's verbs, one file each; `main.rs` parses the arguments and calls them.
//!
//! - [`run`]: the main job, pick cycles until the table is clear.
//! - [`session`]: one run on a robot server, shared by `run` and `eval run`.
//! - [`eval_run`]: seeded runs judged against the simulation's truth.
//! - [`eval_run_batch`]: `eval run` over a seed range: shards, records per scene, merging.
//! - [`eval_locate`]: the matcher over seeded scenes against the truth, batched the same way.
//! - [`eval_pairs`]: the matcher on pairs imaged anywhere (folders of scenes), against their truth.
//! - [`pair_truth`]: a pair's truth from `marvin render`'s scene.json, for `locate` and `eval pairs`.
//! - [`batch`]: the scene loop batched verbs share (`--shard`, `--out`, `--resume`, `--jobs`).
//! - [`scene`]: a seeded scene rendered and through the front end, for `locate` and `eval`.
//! - [`render`]: settle a world and render both cameras.
//! - [`edges`]: Canny and edge strings of any image.
//! - [`stereo`]: the front end on any stereo pair.
//! - [`locate`]: render, front end and matcher on one scene, against the truth.
//! - [`locate_pair`]: front end and matcher on any stereo pair and its cameras, no truth.
//! - [`pick`]: physical picks with the simulated arm.
//! - [`calibrate`]: hand-eye calibration through the robot server, and its evaluation.
//! - [`calibrate_cameras`]: camera calibration from the board through the robot server.
//! - [`cameras`]: where a client's cameras come from (a file, the server, or measured first).
//! - [`serve`]: the simulated cell and the robot server behind a socket.
//! - [`table`]: the table as `run` knows it (hand-eye transform and layout), for `locate`.
//! - [`eval`], [`eval_pick`]: the pipeline over seeded scenes, against the truth.
//! - [`bench`]: medians of how fast things run.
//! - [`output`]: printing that tolerates a reader going away, progress, settling with a warning.
//! - [`args`]: parsers and limits for the command line's numbers.

pub mod args;
pub mod batch;
pub mod bench;
pub mod calibrate;
pub mod calibrate_cameras;
pub mod cameras;
pub mod edges;
pub mod eval;
pub mod eval_calibrate;
pub mod eval_locate;
pub mod eval_pairs;
pub mod eval_pick;
pub mod eval_run;
pub mod eval_run_batch;
pub mod eval_vision;
pub mod locate;
pub mod locate_pair;
pub mod output;
pub mod pair_truth;
pub mod pick;
pub mod render;
pub mod run;
pub mod scene;
pub mod serve;
pub mod session;
pub mod stereo;
pub mod table;
