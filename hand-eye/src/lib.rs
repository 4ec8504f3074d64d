//! Hand-eye calibration: the camera-to-robot transform from flag sightings by least squares,
//! degeneracy checks, and the calibration file the kinematics server reads.
//!
//! Not built yet: the hand-eye issue fills this crate. It depends on neither `sim` nor `vision`.
