//! Where the front end looks for matches: no nearer than the rig's workspace allows, and not
//! under the table the parts rest on.
//!
//! Without a table, PMF searches the disparities of depths [`WORKSPACE_DEPTH_M`] along the
//! rectified axis, MARVIN's constant workspace. Where the cell's layout places the table (the
//! run has it from the hand-eye calibration and the robot server's table height), nothing in
//! view lies under its top: the table seen through a rectified pixel `(x, y)` of the left image
//! is at disparity `-B (n . ((x - cx), (y - cy), f)) / h`, affine in `x` and `y` (`n` the top's
//! upward normal in the rectified frame, `h` the camera's height above it, `B` the baseline).
//! A candidate whose disparity puts it further than that, less [`FLOOR_MARGIN_M`], is refused
//! before PMF weighs it; the right match of a texture edgel, a shadow's edge or a part's bottom
//! edge lies on the top and is kept.

use super::rectify::Rectification;
use nalgebra::{Isometry3, Point3, Vector3};
use serde::{Deserialize, Serialize};

/// Depths (metres, along the rectified axis) the calibrated front end searches where nothing
/// places the table: MARVIN's workspace, a table 0.6 to 1.6 m from the cameras. The nearest
/// bound also holds with a table (the arm comes into view above the parts).
pub const WORKSPACE_DEPTH_M: (f64, f64) = (0.6, 1.6);

/// How far under the table's top (metres) a match may put its edge. The table comes from the
/// hand-eye calibration, a few millimetres off (3.1 mm on the reporting range of issue 48), and
/// a disparity 0.5 px off is 2-4 mm of depth at 0.8-1.2 m; see docs/TUNING.md, "The disparity
/// search from the table", for the margins tried.
pub const FLOOR_MARGIN_M: f64 = 0.015;

/// The table's top in the `cam` frame, where the parts rest: its upward unit normal and the
/// height of `cam`'s origin above it. The matcher refuses readings through it
/// (`matcher::table`); the front end searches no disparity under it ([`DisparityPlane::floor`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Table {
    pub up: [f64; 3],
    /// `cam`'s origin above the top, metres.
    pub camera_height_m: f64,
}

impl Table {
    /// The table whose top is the plane z = 0 of a frame `cam_from_table` places (z up).
    pub fn from_cam_from_table(cam_from_table: &Isometry3<f64>) -> Table {
        let up = cam_from_table.rotation * Vector3::z();
        let top = Point3::from(cam_from_table.translation.vector);
        Table { up: up.into(), camera_height_m: -up.dot(&top.coords) }
    }

    /// A frame whose plane z = 0 is the top, z up (`cam_from_table`), its origin the foot of
    /// the camera's perpendicular on the top.
    pub fn cam_from_table(&self) -> Isometry3<f64> {
        let up = Vector3::from(self.up);
        let rotation = nalgebra::UnitQuaternion::rotation_between(&Vector3::z(), &up)
            .unwrap_or_else(|| nalgebra::UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        Isometry3::from_parts((-self.camera_height_m * up).into(), rotation)
    }

    /// How high `x` (`cam`) lies above the top, metres (negative under it).
    pub fn height_of(&self, x: &Point3<f64>) -> f64 {
        Vector3::from(self.up).dot(&x.coords) + self.camera_height_m
    }
}

/// A disparity that is affine over the left rectified image: `a x + b y + c`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DisparityPlane {
    pub a: f32,
    pub b: f32,
    pub c: f32,
}

impl DisparityPlane {
    /// The disparity at rectified left position `(x, y)`.
    pub fn at(&self, x: f32, y: f32) -> f32 {
        self.a * x + self.b * y + self.c
    }

    /// The disparity of the plane `below_m` metres under `table`'s top, over the left rectified
    /// image (negative where rays pass above that plane's horizon: nothing is refused there).
    pub fn floor(rect: &Rectification, table: &Table, below_m: f64) -> DisparityPlane {
        let n = rect.rect_from_left * Vector3::from(table.up);
        let scale = -rect.baseline / (table.camera_height_m + below_m);
        DisparityPlane {
            a: (scale * n.x) as f32,
            b: (scale * n.y) as f32,
            c: (scale * (n.z * rect.f - n.x * rect.cx - n.y * rect.cy)) as f32,
        }
    }
}

/// What the front end knows of the cell beyond the cameras.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Workspace {
    /// The table's top, where the cell's layout places it.
    pub table: Option<Table>,
}

impl Workspace {
    /// The disparity range PMF searches, and the floor under it where the table is known.
    pub fn search(&self, rect: &Rectification) -> (f32, f32, Option<DisparityPlane>) {
        let (min, max) = disparity_range(rect, WORKSPACE_DEPTH_M.0, WORKSPACE_DEPTH_M.1);
        (min, max, self.table.map(|t| DisparityPlane::floor(rect, &t, FLOOR_MARGIN_M)))
    }
}

/// The disparity range that depths from `near` to `far` metres (along the rectified axis) give.
pub fn disparity_range(rect: &Rectification, near: f64, far: f64) -> (f32, f32) {
    ((rect.f * rect.baseline / far) as f32, (rect.f * rect.baseline / near) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::front_end::rectify::tests::camera_at;
    use mesh::StereoCalibration;

    /// The verged rig of `worlds/widgets.toml`, whose world frame's z = 0 is the table's top.
    fn rig() -> (StereoCalibration, Rectification) {
        let calib = StereoCalibration {
            left: camera_at(Point3::new(-0.1, -0.6894, 0.5785)),
            right: camera_at(Point3::new(0.1, -0.6894, 0.5785)),
        };
        let rect = Rectification::new(&calib);
        (calib, rect)
    }

    /// Where the left rectified camera sees `p` (`cam`).
    fn rectified_left(rect: &Rectification, p: &Point3<f64>) -> (f32, f32) {
        let q = rect.rect_from_left * p.coords;
        ((rect.f * q.x / q.z + rect.cx) as f32, (rect.f * q.y / q.z + rect.cy) as f32)
    }

    #[test]
    fn the_floor_is_the_disparity_of_points_on_the_plane_under_the_top() {
        let (calib, rect) = rig();
        let cam_from_world = calib.left.world_from_cam.inverse();
        let table = Table::from_cam_from_table(&cam_from_world);
        let floor = DisparityPlane::floor(&rect, &table, 0.01);
        // Points 10 mm under the top, across the view: their own disparity, triangulated
        // independently by the rectification, is the floor's at their rectified position.
        for (x, y) in [(0.0, 0.0), (0.15, -0.1), (-0.2, 0.3), (0.05, 0.25)] {
            let p = cam_from_world * Point3::new(x, y, -0.01);
            let d = rect.disparity_of(&p);
            let (xr, yr) = rectified_left(&rect, &p);
            assert!((floor.at(xr, yr) as f64 - d).abs() < 1e-3, "at ({x}, {y}): {d}");
        }
        // A point on the top is nearer than the floor (a larger disparity).
        let on_top = cam_from_world * Point3::new(0.0, 0.0, 0.0);
        let (xr, yr) = rectified_left(&rect, &on_top);
        assert!(rect.disparity_of(&on_top) > floor.at(xr, yr) as f64 + 1.0);
    }

    /// A table's frame gives back the table it was made from, and its origin lies on the top.
    #[test]
    fn a_tables_frame_gives_back_the_table() {
        let (calib, _) = rig();
        let table = Table::from_cam_from_table(&calib.left.world_from_cam.inverse());
        let frame = table.cam_from_table();
        let again = Table::from_cam_from_table(&frame);
        assert!((Vector3::from(again.up) - Vector3::from(table.up)).norm() < 1e-12);
        assert!((again.camera_height_m - table.camera_height_m).abs() < 1e-12);
        assert!(table.height_of(&(frame * Point3::origin())).abs() < 1e-12);
        let above = frame * Point3::new(0.03, -0.02, 0.01);
        assert!((table.height_of(&above) - 0.01).abs() < 1e-12);
    }

    #[test]
    fn without_a_table_the_search_is_the_workspace_and_has_no_floor() {
        let (_, rect) = rig();
        let (min, max, floor) = Workspace::default().search(&rect);
        assert!(floor.is_none());
        assert!((min as f64 - rect.f * rect.baseline / 1.6).abs() < 1e-3);
        assert!((max as f64 - rect.f * rect.baseline / 0.6).abs() < 1e-3);
    }
}
