//! Hand-eye calibration, as MARVIN did it: "using TINA to locate a flag held in the gripper of
//! the robot arm ... repeated numerous times in various positions of the robot workspace. A
//! least-squares method is used to obtain the best transformation."
//!
//! From sightings -- `base_from_gripper` as the robot reports it, `cam_from_flag` as vision
//! measures it -- it solves `cam_from_base` and `gripper_from_flag` together, from
//! `cam_from_flag = cam_from_base * base_from_gripper * gripper_from_flag`:
//!
//! - [`sighting`]: one sighting: the gripper pose the robot reports, the flag pose vision sees.
//! - [`motion`]: whether the sightings can determine the answer at all (enough of them, turning
//!   the gripper about more than one axis), and if not, what motion is missing.
//! - [`symmetry`]: a symmetric flag's readings made to agree (it is seen only up to its
//!   symmetry, and not the same way in every sighting).
//! - [`closed_form`]: a closed-form start: `AX = XB` on the relative motions (rotation from
//!   their axes, then translation, by linear least squares), then the flag in the gripper.
//! - [`refine`]: nonlinear least squares (Levenberg-Marquardt) on the flag's points, and the
//!   covariance of the result.
//! - [`solve`]: the whole routine: checks, start, refinement, outlier sightings found and
//!   dropped (and said which), residuals in mm and degrees.
//! - [`pose`]: poses as files and JSON hold them, and the rotation-vector helpers.
//! - [`file`]: the calibration file (`out/hand_eye.json`) that the robot server reads.
//!
//! Pure mathematics on nalgebra: it depends on neither `sim` nor `vision`.

pub mod closed_form;
pub mod file;
pub mod motion;
pub mod pose;
pub mod refine;
pub mod sighting;
pub mod solve;
pub mod symmetry;

pub use file::HandEyeFile;
pub use pose::PoseJson;
pub use solve::{HandEyeError, Sighting, Solution, SolveParams, solve};
