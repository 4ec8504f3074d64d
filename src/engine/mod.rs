//! The MARVIN side: what runs on images and talks to the robot server, and only through
//! [`crate::protocol`] (never the server's own code).
//!
//! - [`client`]: a typed client of the robot server.
//! - [`perception`]: what a capture becomes: images, calibration, front end, located parts.
//! - [`run`]: the end-to-end cycle over the socket.
//! - [`calibrate`]: hand-eye calibration from sightings of the flag.
//! - [`calibrate_cameras`]: camera calibration from views of the board.
//! - [`recording`]: rerun recordings of runs and calibrations.

pub mod calibrate;
pub mod calibrate_cameras;
pub mod client;
pub mod perception;
pub mod recording;
pub mod run;
