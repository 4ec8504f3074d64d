//! The MARVIN rebuild's top level: what wires the crates together.
//!
//! - [`front_end`]: the vision front end (re-exported from `vision`), as the CLI and the
//!   evaluations call it.
//! - [`truth`]: ground truth for evaluation only: exact ray casts into a settled scene.
//! - [`eval`]: the front end's results against that truth.

pub mod eval;
pub use vision::front_end;
pub mod truth;
