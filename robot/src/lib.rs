//! The UMI-style arm: kinematics from the URDF, trajectories, path planning, and the
//! kinematics/path server with its protocol.
//!
//! Not built yet: the arm issue fills this crate. It depends on neither `sim` nor `vision`.
