//! The emulated MARVIN/TINA vision pipeline. It sees images, a stereo calibration
//! ([`mesh::StereoCalibration`]) and the model library, never the simulation.
//!
//! Not built yet: Canny, edge strings, rectified edges, PMF stereo, 2D and 3D lines and the
//! Joiner arrive with the front-end issue; the model matcher with the matching issue.
