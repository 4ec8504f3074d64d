//! The MARVIN rebuild's top level: what wires the crates together.
//!
//! - [`front_end`]: the vision front end (re-exported from `vision`), as the CLI and the
//!   evaluations call it.
//! - [`truth`]: ground truth for evaluation only: exact ray casts into a settled scene.
//! - [`eval`]: the front end's results against that truth.
//! - [`pick`]: physical pick and place: the arm in the rapier cell, plans executed by its
//!   motors, outcomes judged from the physics.
//! - [`perception`]: what a capture becomes: images, the stereo head's calibration, the front
//!   end's output, located parts or the calibration flag.
//! - [`recording`]: rerun recordings of runs (the `rerun` feature, on by default).
//! - [`run`]: the end-to-end cycle: park, capture, locate, choose, pick over the socket.
//! - [`server`]: the robot server: the simulated cell behind a TCP socket.
//! - [`calibrate`]: hand-eye calibration through the robot server: the flag carried to poses,
//!   seen, located, and the sightings solved.
//! - [`calibrate_cameras`]: camera calibration through the robot server: the board carried
//!   to poses, its corners found in both images, the views solved (`camera_calib`).
//! - [`client`]: a typed client of the robot server.
//! - [`protocol`]: protocol v1 between the MARVIN side and the robot server, as typed
//!   requests and replies shared by both.

pub mod calibrate;
pub mod calibrate_cameras;
pub mod client;
pub mod eval;
pub mod perception;
pub mod pick;
pub mod protocol;
pub mod recording;
pub mod run;
pub mod server;
pub use vision::front_end;
pub mod truth;
