//! The MARVIN rebuild's top level: what wires the crates together, in three parts that meet
//! only at the socket, and evaluation apart.
//!
//! - [`engine`], the MARVIN side: what runs on images and talks to the robot server.
//!   - [`engine::client`]: a typed client of the robot server.
//!   - [`engine::perception`]: what a capture becomes: images, the stereo head's calibration,
//!     the front end's output, located parts or the calibration flag.
//!   - [`engine::run`]: the end-to-end cycle: park, capture, locate, choose, pick over the socket.
//!   - [`engine::calibrate`]: hand-eye calibration through the robot server: the flag carried to
//!     poses, seen, located, and the sightings solved.
//!   - [`engine::calibrate_cameras`]: camera calibration through the robot server: the board
//!     carried to poses, its corners found in both images, the views solved (`camera_calib`).
//!   - [`engine::recording`]: rerun recordings of runs (the `rerun` feature, on by default).
//! - [`protocol`]: protocol v1 between the two sides, as typed requests and replies shared by
//!   both (`docs/PROTOCOL.md`).
//! - [`server`], the robot server's side: the simulated cell behind a TCP socket.
//!   - [`server::cell`]: the cell's thread, serving one job at a time.
//!   - [`server::pick`]: physical pick and place: the arm in the rapier cell, plans executed by
//!     its motors, outcomes judged from the physics ([`server::judge`]).
//! - [`eval`], apart from both: the front end's and the matcher's results against the truth
//!   ([`eval::truth`]: exact ray casts into a settled scene).
//! - [`front_end`]: the vision front end (re-exported from `vision`), as the CLI and the
//!   evaluations call it.
//!
//! `tests/layout.rs` checks that no file of one side names the other except through
//! [`protocol`].

pub mod engine;
pub mod eval;
pub mod protocol;
pub mod server;
pub use vision::front_end;
