//! Rectification of edge locations (not of images): the verged cameras are replaced by a
//! parallel pair sharing one rotation and one set of intrinsics, so that a rectified row is an
//! epipolar line in both and disparity is `x_left - x_right` (the Middlebury convention).
//!
//! A camera with a measured lens distortion has its edge locations corrected first (each to
//! where an ideal pinhole of the same intrinsics would see it, as TINA rectified edge locations
//! from its calibration), without resampling the image.
//!
//! Rectified frame: `x` along the baseline (left centre to right centre), `z` the mean of the two
//! optical axes made perpendicular to it, `y = z x x` (down in the image, as in the cameras).

use super::canny::Edgel;
use mesh::{PinholeCamera, StereoCalibration};
use nalgebra::{Matrix3, Point3, Rotation3, Vector3};

/// Which camera an edge came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Left,
    Right,
}

/// The parallel-camera geometry of a calibrated verged pair.
#[derive(Debug, Clone, PartialEq)]
pub struct Rectification {
    /// Focal length of both rectified cameras, pixels.
    pub f: f64,
    /// Principal point of both rectified cameras.
    pub cx: f64,
    pub cy: f64,
    /// Distance between the camera centres, metres.
    pub baseline: f64,
    /// Maps left-camera (`cam`) directions into the rectified frame.
    pub rect_from_left: Rotation3<f64>,
    pub rect_from_right: Rotation3<f64>,
    left_k_inv: Matrix3<f64>,
    right_k_inv: Matrix3<f64>,
    left_k: Matrix3<f64>,
    right_k: Matrix3<f64>,
    /// The cameras themselves, for their lenses.
    left: PinholeCamera,
    right: PinholeCamera,
}

fn k_matrix(c: &PinholeCamera) -> Matrix3<f64> {
    Matrix3::new(c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0)
}

impl Rectification {
    pub fn new(calib: &StereoCalibration) -> Rectification {
        let (l, r) = (&calib.left, &calib.right);
        let baseline_w = r.centre() - l.centre();
        let x = baseline_w.normalize();
        let axis = |c: &PinholeCamera| c.world_from_cam.rotation * Vector3::z();
        let mean_axis = (axis(l) + axis(r)).normalize();
        let z = (mean_axis - x * x.dot(&mean_axis)).normalize();
        let y = z.cross(&x);
        let world_from_rect = Rotation3::from_basis_unchecked(&[x, y, z]);
        let rect_from = |c: &PinholeCamera| world_from_rect.inverse() * c.world_from_cam.rotation.to_rotation_matrix();
        let k = |c: &PinholeCamera| k_matrix(c);
        Rectification {
            f: l.fx,
            cx: l.cx,
            cy: l.cy,
            baseline: baseline_w.norm(),
            rect_from_left: rect_from(l),
            rect_from_right: rect_from(r),
            left_k_inv: k(l).try_inverse().expect("focal lengths are positive"),
            right_k_inv: k(r).try_inverse().expect("focal lengths are positive"),
            left_k: k(l),
            right_k: k(r),
            left: l.clone(),
            right: r.clone(),
        }
    }

    fn rect_k(&self) -> Matrix3<f64> {
        Matrix3::new(self.f, 0.0, self.cx, 0.0, self.f, self.cy, 0.0, 0.0, 1.0)
    }

    /// The homography from a camera's pixels to rectified pixels.
    pub fn homography(&self, side: Side) -> Matrix3<f64> {
        let (rot, k_inv) = match side {
            Side::Left => (&self.rect_from_left, &self.left_k_inv),
            Side::Right => (&self.rect_from_right, &self.right_k_inv),
        };
        self.rect_k() * rot.matrix() * k_inv
    }

    /// The homography from rectified pixels back to a camera's pixels.
    pub fn inverse_homography(&self, side: Side) -> Matrix3<f64> {
        let (rot, k) = match side {
            Side::Left => (&self.rect_from_left, &self.left_k),
            Side::Right => (&self.rect_from_right, &self.right_k),
        };
        k * rot.inverse().matrix() * self.rect_k().try_inverse().expect("f > 0")
    }

    fn camera(&self, side: Side) -> &PinholeCamera {
        match side {
            Side::Left => &self.left,
            Side::Right => &self.right,
        }
    }

    /// Rectified position of pixel `(x, y)` of one camera (corrected for its lens first).
    pub fn to_rectified(&self, side: Side, x: f64, y: f64) -> (f64, f64) {
        let (x, y) = self.camera(side).undistort_px(x, y);
        apply(&self.homography(side), x, y)
    }

    /// A camera's pixel seen at rectified position `(x, y)` (through its lens).
    pub fn from_rectified(&self, side: Side, x: f64, y: f64) -> (f64, f64) {
        let (x, y) = apply(&self.inverse_homography(side), x, y);
        self.camera(side).distort_px(x, y)
    }

    /// Rectifies edgels: positions, and orientations through the mapping's local Jacobian.
    pub fn rectify_edgels(&self, side: Side, edgels: &[Edgel]) -> Vec<Edgel> {
        let h = self.homography(side);
        let mut lens = LensWalk { cam: self.camera(side), last: None };
        edgels
            .iter()
            .map(|e| {
                let (x, y) = (e.x as f64, e.y as f64);
                let ((ux, uy), step) = lens.undistort(x, y);
                let (rx, ry) = apply(&h, ux, uy);
                // The edge runs along the tangent (perpendicular to the gradient); map a point a
                // pixel along it and turn the mapped tangent back into a gradient direction.
                let (s, c) = (e.orientation as f64).sin_cos();
                let (dx, dy) = (step[0][0] * -s + step[0][1] * c, step[1][0] * -s + step[1][1] * c);
                let (tx, ty) = apply(&h, ux + dx, uy + dy);
                // Tangent (-sin, cos) of the gradient angle: angle = atan2(-tangent.x, tangent.y).
                let orientation = (-(tx - rx)).atan2(ty - ry);
                Edgel { x: rx as f32, y: ry as f32, orientation: orientation as f32, ..*e }
            })
            .collect()
    }

    /// The point, in the left camera's (`cam`) frame, seen at rectified left position
    /// `(x, y)` with disparity `d`.
    pub fn triangulate(&self, x: f64, y: f64, d: f64) -> Point3<f64> {
        let z = self.f * self.baseline / d;
        let in_rect = Vector3::new((x - self.cx) * z / self.f, (y - self.cy) * z / self.f, z);
        Point3::from(self.rect_from_left.inverse() * in_rect)
    }

    /// Disparity of a point given in the left camera's frame (for evaluation and limits).
    pub fn disparity_of(&self, p_cam: &Point3<f64>) -> f64 {
        let in_rect = self.rect_from_left * p_cam.coords;
        self.f * self.baseline / in_rect.z
    }
}

/// A camera's pixels corrected for its lens one after another, each started from the one
/// before where that lies near ([`NEAR_PX`]): an image's edgels come in raster order, mostly a
/// pixel or two from the last. Why: undistortion is iterative, and from the distorted point it
/// took 4-5 Newton steps an edgel, twice over (the orientation's second point too); through
/// tuning seed 1's measured lenses `undistort` was the largest cost the realistic cell added
/// to `marvin bench vision` (601 of 8739 samples under `perf`).
struct LensWalk<'c> {
    cam: &'c PinholeCamera,
    /// The last pixel, its ideal normalised point and the inverse Jacobian there.
    last: Option<LastPixel>,
}

/// See [`LensWalk::last`].
type LastPixel = ((f64, f64), (f64, f64), [[f64; 2]; 2]);

/// A pixel this near the last one (in each of `u`, `v`) starts from its answer.
const NEAR_PX: f64 = 16.0;

impl LensWalk<'_> {
    /// Where an ideal pinhole sees pixel `(u, v)` ([`PinholeCamera::undistort_px`]), and how a
    /// small step from it moves there: `[[dx/du, dx/dv], [dy/du, dy/dv]]` in pixels.
    fn undistort(&mut self, u: f64, v: f64) -> ((f64, f64), [[f64; 2]; 2]) {
        let cam = self.cam;
        let lens = &cam.distortion;
        if lens.is_none() {
            return ((u, v), [[1.0, 0.0], [0.0, 1.0]]);
        }
        let d = ((u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy);
        let start = match self.last {
            Some((px, ideal, j)) if (u - px.0).abs() < NEAR_PX && (v - px.1).abs() < NEAR_PX => {
                let (dx, dy) = ((u - px.0) / cam.fx, (v - px.1) / cam.fy);
                (ideal.0 + j[0][0] * dx + j[0][1] * dy, ideal.1 + j[1][0] * dx + j[1][1] * dy)
            }
            _ => d,
        };
        let ideal = lens.undistort_from(d, start).unwrap_or(d);
        let j = lens.inverse_jacobian(ideal.0, ideal.1).unwrap_or([[1.0, 0.0], [0.0, 1.0]]);
        self.last = Some(((u, v), ideal, j));
        let (sx, sy) = (cam.fx, cam.fy);
        let step = [[j[0][0], j[0][1] * sx / sy], [j[1][0] * sy / sx, j[1][1]]];
        ((sx * ideal.0 + cam.cx, sy * ideal.1 + cam.cy), step)
    }
}

fn apply(h: &Matrix3<f64>, x: f64, y: f64) -> (f64, f64) {
    let p = h * Vector3::new(x, y, 1.0);
    (p.x / p.z, p.y / p.z)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A 512x512 camera of 1000 px focal length at `eye`, looking at the world's origin, `z` up.
    pub(crate) fn camera_at(eye: Point3<f64>) -> PinholeCamera {
        PinholeCamera::looking_at((512, 512), 1000.0, [255.5, 255.5], eye, Point3::origin(), Vector3::z())
    }

    /// The default world's rig: 0.2 m baseline, 0.9 m from the origin, looking down 40 deg.
    pub(crate) fn verged_pair() -> StereoCalibration {
        let cam = |x: f64| camera_at(Point3::new(x, -0.6894, 0.5785));
        StereoCalibration { left: cam(-0.1), right: cam(0.1) }
    }

    #[test]
    fn rectified_rows_are_epipolar_lines_and_points_come_back() {
        let calib = verged_pair();
        let rect = Rectification::new(&calib);
        assert!((rect.baseline - 0.2).abs() < 1e-12);
        for p in [Point3::new(0.0, 0.0, 0.0), Point3::new(0.1, -0.05, 0.03), Point3::new(-0.12, 0.15, 0.08)] {
            let (l, r) = (calib.left.project_world(&p).unwrap(), calib.right.project_world(&p).unwrap());
            let (lx, ly) = rect.to_rectified(Side::Left, l.x, l.y);
            let (rx, ry) = rect.to_rectified(Side::Right, r.x, r.y);
            assert!((ly - ry).abs() < 1e-9, "rows differ: {ly} vs {ry}");
            let d = lx - rx;
            let p_cam = calib.left.world_from_cam.inverse_transform_point(&p);
            assert!((d - rect.disparity_of(&p_cam)).abs() < 1e-9);
            assert!((rect.triangulate(lx, ly, d) - p_cam).norm() < 1e-12);
        }
    }

    #[test]
    fn through_lenses_rows_are_still_epipolar_lines_and_points_come_back() {
        let mut calib = verged_pair();
        calib.left.distortion = mesh::distortion::PlumbBob::from_d([-0.2, 0.09, 3e-4, -2e-4, 0.0]);
        calib.right.distortion = mesh::distortion::PlumbBob::from_d([-0.19, 0.08, -2e-4, 3e-4, 0.0]);
        let rect = Rectification::new(&calib);
        for p in [Point3::new(0.0, 0.0, 0.0), Point3::new(0.15, -0.12, 0.03), Point3::new(-0.14, 0.16, 0.08)] {
            let (l, r) = (calib.left.project_world(&p).unwrap(), calib.right.project_world(&p).unwrap());
            let (lx, ly) = rect.to_rectified(Side::Left, l.x, l.y);
            let (rx, ry) = rect.to_rectified(Side::Right, r.x, r.y);
            assert!((ly - ry).abs() < 1e-8, "rows differ: {ly} vs {ry}");
            let p_cam = calib.left.world_from_cam.inverse_transform_point(&p);
            assert!((rect.triangulate(lx, ly, lx - rx) - p_cam).norm() < 1e-9);
            let back = rect.from_rectified(Side::Left, lx, ly);
            assert!((back.0 - l.x).abs() < 1e-8 && (back.1 - l.y).abs() < 1e-8);
        }
        // Without the correction the same point would land pixels away.
        let pinholes = Rectification::new(&verged_pair());
        let l = calib.left.project_world(&Point3::new(0.15, -0.12, 0.03)).unwrap();
        let (a, b) = (pinholes.to_rectified(Side::Left, l.x, l.y), rect.to_rectified(Side::Left, l.x, l.y));
        assert!((a.0 - b.0).hypot(a.1 - b.1) > 1.0, "the lens moved the point by {a:?} -> {b:?} only");
    }

    #[test]
    fn edgels_through_a_lens_land_where_each_pixel_alone_does() {
        // Edgels in raster order, each one's lens correction started from the one before (some
        // near it, some across the image): each must land where its pixel alone maps, with the
        // orientation of a pixel's step along its edge mapped alone.
        let mut calib = verged_pair();
        calib.right.distortion = mesh::distortion::PlumbBob::from_d([-0.2, 0.16, 4e-4, -1e-4, 0.0]);
        let rect = Rectification::new(&calib);
        let edgel = |x: f64, y: f64, orientation: f64| Edgel {
            x: x as f32,
            y: y as f32,
            orientation: orientation as f32,
            contrast: 10.0,
            sides: [0.0; 2],
        };
        let edgels: Vec<Edgel> = (0..400)
            .map(|k| {
                let (row, col) = (k / 40, k % 40);
                let x = if col % 7 == 3 { 500.0 - col as f64 } else { 3.0 + col as f64 * 1.3 };
                edgel(x, 2.0 + row as f64 * 50.0, k as f64 * 0.37)
            })
            .collect();
        for (e, r) in edgels.iter().zip(rect.rectify_edgels(Side::Right, &edgels)) {
            let (x, y) = rect.to_rectified(Side::Right, e.x as f64, e.y as f64);
            assert!((r.x as f64 - x).abs() < 1e-3 && (r.y as f64 - y).abs() < 1e-3, "{e:?} -> {r:?}, alone ({x}, {y})");
            let (s, c) = (e.orientation as f64).sin_cos();
            let (tx, ty) = rect.to_rectified(Side::Right, e.x as f64 - s, e.y as f64 + c);
            let alone = (-(tx - x)).atan2(ty - y);
            let turn = (r.orientation as f64 - alone + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            assert!(turn.abs() < 1e-3, "{e:?}: orientation {} against {alone}", r.orientation);
        }
    }

    #[test]
    fn inverse_homography_undoes_the_homography() {
        let rect = Rectification::new(&verged_pair());
        for side in [Side::Left, Side::Right] {
            let (rx, ry) = rect.to_rectified(side, 100.0, 400.0);
            let back = apply(&rect.inverse_homography(side), rx, ry);
            assert!((back.0 - 100.0).abs() < 1e-9 && (back.1 - 400.0).abs() < 1e-9);
        }
    }

    #[test]
    fn edgel_orientation_follows_the_warp() {
        let calib = verged_pair();
        let rect = Rectification::new(&calib);
        // A world line seen by the left camera: its rectified image must have the direction the
        // rectified edgel's tangent claims.
        let (a, b) = (Point3::new(-0.05, 0.02, 0.0), Point3::new(0.06, 0.07, 0.0));
        let (pa, pb) = (calib.left.project_world(&a).unwrap(), calib.left.project_world(&b).unwrap());
        let mid = (pa + pb.coords) / 2.0;
        let t = (pb - pa).normalize();
        let e = Edgel {
            x: mid.x as f32,
            y: mid.y as f32,
            orientation: t.x.atan2(-t.y) as f32,
            contrast: 10.0,
            sides: [0.0; 2],
        };
        let r = rect.rectify_edgels(Side::Left, &[e])[0];
        let (ra, rb) = (rect.to_rectified(Side::Left, pa.x, pa.y), rect.to_rectified(Side::Left, pb.x, pb.y));
        let rt = Vector3::new(rb.0 - ra.0, rb.1 - ra.1, 0.0).normalize();
        let tangent = Vector3::new(-(r.orientation as f64).sin(), (r.orientation as f64).cos(), 0.0);
        assert!(tangent.cross(&rt).norm() < 1e-4, "tangent {tangent} vs {rt}");
        // The warp turns the image by a few degrees only, so the gradient keeps its sense.
        let turn = (r.orientation - e.orientation + std::f32::consts::PI).rem_euclid(std::f32::consts::TAU)
            - std::f32::consts::PI;
        assert!(turn.abs() < 0.3, "gradient turned by {turn} rad");
    }
}
