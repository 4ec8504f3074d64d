//! The MARVIN rebuild's top level: what wires the crates together.
//!
//! - [`front_end`]: the vision front end (re-exported from `vision`), as the CLI and the
//!   evaluations call it.
//! - [`truth`]: ground truth for evaluation only: exact ray casts into a settled scene.
//! - [`eval`]: the front end's results against that truth.
//! - [`pick`]: physical pick and place: the arm in the rapier cell, plans executed by its
//!   motors, outcomes judged from the physics.
//! - [`server`]: the robot server: the simulated cell behind a TCP socket.
//! - [`client`]: a typed client of the robot server.
//! - [`protocol`]: protocol v1 between the MARVIN side and the robot server, as typed
//!   requests and replies shared by both.

pub mod client;
pub mod eval;
pub mod pick;
pub mod protocol;
pub mod server;
pub use vision::front_end;
pub mod truth;
