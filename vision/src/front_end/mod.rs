//! The front end: the first of MARVIN's two phases, scene geometry from stereo. A stereo pair
//! in, the 3D lines of the scene (and what led to them) out, as TINA computed them.
//!
//! - [`canny`](mod@canny): Canny edges (sigma 1, separable Gaussian) located to sub-pixel acuity.
//! - `blur`: the image's blur, measured from its strongest edgels, for Canny's placement of
//!   edgels beside parallel steps.
//! - [`noise`]: each image's own noise, and Canny's thresholds raised above it.
//! - [`strings`]: edgels linked into ordered 8-connected edge strings.
//! - [`photometric`]: the right camera's grey levels as the left's, measured from PMF's own
//!   matches (cameras differ in gain, black level and response).
//! - [`rectify`]: edge locations mapped into a parallel-camera geometry (rows are epipolars).
//! - [`pmf`]: PMF stereo matching of rectified edgels.
//! - [`lines2d`]: strings cut into straight lines by recursive fit and segment.
//! - [`lines3d`]: disparity fitted along each 2D line, its ends triangulated into 3D segments.
//! - [`flat_lines`]: lines along the rasters, which PMF cannot match, matched whole between the images.
//! - [`pipeline`]: the stages above run in order on one whole stereo pair ([`FrontEnd`]).
//! - [`workspace`]: the disparities searched: the rig's workspace, and nothing under the table.
//! - [`table_top`]: the table's top found in the 3D lines, where no cell layout places it.
//! - [`soft_edges`]: 3D lines on the table with soft edges (shadows, texture) set apart.
//! - [`slices`]: the same cut into 8 horizontal slice pairs run in parallel, and the Joiner.
//!
//! Nothing here knows of the matcher: it takes the front end's output as it is.

mod blur;
pub mod canny;
pub mod flat_lines;
pub mod lines2d;
pub mod lines3d;
pub mod noise;
pub mod photometric;
pub mod pipeline;
pub mod pmf;
pub mod rectify;
pub mod slices;
pub mod soft_edges;
pub mod strings;
pub mod table_top;
pub mod workspace;

pub use pipeline::{FrontEnd, Geometry, MIN_STRING, Stopwatch, run, run_with};
pub use workspace::{Table, WORKSPACE_DEPTH_M, Workspace, disparity_range};
