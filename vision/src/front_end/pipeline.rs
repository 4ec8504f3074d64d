//! The vision front end on one stereo pair: what `marvin stereo` and `marvin eval vision` run.

use super::canny::{CannyParams, EdgeMap, Edgel};
use super::flat_lines::{Images, match_flat_lines};
use super::lines2d::Line2;
use super::lines3d::{Line3, Lines3dParams, complete_flat_lines, fit_lines3d, lines2d_split_at_depth_breaks};
use super::pmf::{Match, PmfParams, pmf, right_figural_continuity};
use super::rectify::{Rectification, Side};
use super::strings::{EdgeString, link_strings};
use super::workspace::Workspace;
use crate::image::GreyImage;
use mesh::StereoCalibration;
use std::time::Instant;

pub use super::strings::MIN_STRING;

/// Everything the front end found in a pair, with the time each stage took.
#[derive(Debug, Clone)]
pub struct FrontEnd {
    pub left: EdgeMap,
    pub right: EdgeMap,
    pub left_strings: Vec<EdgeString>,
    pub left_rectified: Vec<Edgel>,
    pub right_rectified: Vec<Edgel>,
    pub matches: Vec<Match>,
    /// 2D lines of the left image, in rectified coordinates.
    pub lines2d: Vec<Line2>,
    /// 3D lines in the `cam` frame (none without a calibration).
    pub lines3d: Vec<Line3>,
    /// 3D lines believed to be shadows or the table's texture, set apart from `lines3d`
    /// ([`super::soft_edges`]; none until the table's top is known).
    pub set_apart: Vec<Line3>,
    /// The rectification used (none for images given already rectified).
    pub rect: Option<Rectification>,
    pub timings_ms: Vec<(&'static str, f64)>,
}

thread_local! {
    /// Canny's buffers, kept per worker thread from frame to frame as MARVIN's resident tasks kept
    /// theirs: fresh megabytes per image cost more in page faults than Canny itself.
    static CANNY: std::cell::RefCell<super::canny::CannyWorkspace> = Default::default();
}

fn canny_reusing(img: &GreyImage, params: &CannyParams) -> EdgeMap {
    let mut out = EdgeMap::default();
    CANNY.with(|ws| ws.borrow_mut().run(img, params, &mut out));
    out
}

/// What the front end knows of the cameras.
#[derive(Debug, Clone)]
pub enum Geometry {
    /// A calibrated verged pair: edges are rectified, disparities limited to the
    /// [`Workspace`]'s.
    Calibrated(Box<StereoCalibration>),
    /// Images already rectified (rows are epipolars), with the disparity range to search.
    Rectified { disparity_min: f32, disparity_max: f32 },
}

/// Times consecutive stages.
pub struct Stopwatch {
    clock: Instant,
    /// Each stage's name and milliseconds, in order.
    pub laps: Vec<(&'static str, f64)>,
}

impl Stopwatch {
    pub fn start() -> Stopwatch {
        Stopwatch { clock: Instant::now(), laps: Vec::new() }
    }

    /// Ends stage `name` (and starts the next).
    pub fn lap(&mut self, name: &'static str) {
        self.laps.push((name, self.clock.elapsed().as_secs_f64() * 1e3));
        self.clock = Instant::now();
    }
}

/// The front end on a calibrated pair, searching `workspace`.
pub fn run(
    left: &GreyImage,
    right: &GreyImage,
    calib: &StereoCalibration,
    workspace: &Workspace,
    canny_params: &CannyParams,
) -> FrontEnd {
    run_with(left, right, &Geometry::Calibrated(Box::new(calib.clone())), workspace, canny_params)
}

/// The front end: Canny on both images, strings of the left, rectification, PMF (searching
/// `workspace`, for a calibrated pair), 2D and 3D lines, the lines along the rasters matched
/// whole ([`super::flat_lines`]); where `workspace` knows the table,
/// the lines on it with soft edges set apart ([`super::soft_edges`]).
pub fn run_with(
    left: &GreyImage,
    right: &GreyImage,
    geometry: &Geometry,
    workspace: &Workspace,
    canny_params: &CannyParams,
) -> FrontEnd {
    let mut watch = Stopwatch::start();
    // Each camera's thresholds above its own noise.
    let (left_params, right_params) = (canny_params.for_image(left), canny_params.for_image(right));
    let (l, r) = rayon::join(|| canny_reusing(left, &left_params), || canny_reusing(right, &right_params));
    watch.lap("canny");
    let left_strings = link_strings(&l, MIN_STRING);
    watch.lap("strings");
    let rect = match geometry {
        Geometry::Calibrated(calib) => Some(Rectification::new(calib)),
        Geometry::Rectified { .. } => None,
    };
    let (left_rectified, right_rectified, (disparity_min, disparity_max, floor)) = match (&rect, geometry) {
        (Some(rect), _) => {
            let left = rect.rectify_edgels(Side::Left, &l.edgels);
            (left, rect.rectify_edgels(Side::Right, &r.edgels), workspace.search(rect))
        }
        (None, Geometry::Rectified { disparity_min, disparity_max }) => {
            (l.edgels.clone(), r.edgels.clone(), (*disparity_min, *disparity_max, None))
        }
        (None, Geometry::Calibrated(_)) => unreachable!("a calibrated pair has a rectification"),
    };
    watch.lap("rectify");
    let params = PmfParams { disparity_min, disparity_max, floor, ..PmfParams::default() };
    let mut matches = pmf(&left_rectified, &right_rectified, &left_strings, &params);
    let right_strings = link_strings(&r, MIN_STRING);
    right_figural_continuity(
        &mut matches,
        (&left_rectified, &left_strings),
        (&right_rectified, &right_strings),
        params.continuity_step,
    );
    watch.lap("pmf");
    let lines2d = lines2d_split_at_depth_breaks(&left_rectified, &left_strings, &matches);
    watch.lap("geom2d");
    let lines3d = rect.as_ref().map_or_else(Vec::new, |rect| {
        let p = Lines3dParams::default();
        let mut lines3d = fit_lines3d(&lines2d, &left_strings, &left_rectified, &matches, rect, &p);
        complete_flat_lines(&lines2d, &left_strings, &mut lines3d, rect, &p, 6);
        let images = Images {
            lines2d: &lines2d,
            left_strings: &left_strings,
            left_rectified: &left_rectified,
            right_strings: &right_strings,
            right_rectified: &right_rectified,
        };
        match_flat_lines(&images, rect, &(disparity_min, disparity_max, floor), &mut lines3d);
        lines3d
    });
    watch.lap("geom3d");
    // What the front end vouches for: the matches that lie on a 3D line and agree with it
    // (within `lines3d::VOUCH_PX` of its fit).
    // Matches off every line (near corners, on short or flat strings, isolated) are dropped.
    if rect.is_some() {
        let mut on_line = vec![false; left_rectified.len()];
        for l in &lines3d {
            for &i in &l.inliers {
                on_line[i as usize] = true;
            }
        }
        matches.retain(|m| on_line[m.left as usize]);
    }
    let mut fe = FrontEnd {
        left: l,
        right: r,
        left_strings,
        left_rectified,
        right_rectified,
        matches,
        lines2d,
        lines3d,
        set_apart: Vec::new(),
        rect,
        timings_ms: watch.laps,
    };
    if let (Some(table), Some(_)) = (&workspace.table, &fe.rect) {
        fe.set_apart_soft_lines(table);
    }
    fe
}

impl FrontEnd {
    /// A 2D line's ends in the left image's own (unrectified) pixels.
    pub fn line2d_in_image(&self, line: &Line2) -> [[f32; 2]; 2] {
        let back = |p: [f32; 2]| match &self.rect {
            Some(rect) => {
                let (x, y) = rect.from_rectified(Side::Left, p[0] as f64, p[1] as f64);
                [x as f32, y as f32]
            }
            None => p,
        };
        [back(line.start), back(line.end)]
    }
}

impl FrontEnd {
    /// Moves the 3D lines on `table`'s top with soft edges (shadows, texture;
    /// [`super::soft_edges`]) from `lines3d` to `set_apart`.
    pub fn set_apart_soft_lines(&mut self, table: &super::Table) {
        let lines = std::mem::take(&mut self.lines3d);
        let (kept, soft) = super::soft_edges::split(lines, &self.left_rectified, table);
        self.lines3d = kept;
        self.set_apart.extend(soft);
    }

    /// Nothing found yet (what the Joiner fills).
    pub fn empty(rect: Option<Rectification>) -> FrontEnd {
        FrontEnd {
            left: EdgeMap::default(),
            right: EdgeMap::default(),
            left_strings: Vec::new(),
            left_rectified: Vec::new(),
            right_rectified: Vec::new(),
            matches: Vec::new(),
            lines2d: Vec::new(),
            lines3d: Vec::new(),
            set_apart: Vec::new(),
            rect,
            timings_ms: Vec::new(),
        }
    }
}
