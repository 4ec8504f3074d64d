//! The pinhole camera model and the stereo calibration the vision pipeline reads.
//!
//! Camera frame: `x` right, `y` down, `z` along the optical axis (into the scene). Pixel
//! `(u, v)`: `u` along image rows, `v` down the image, pixel centres at integer coordinates,
//! so `u = fx * x / z + cx`. The stereo rig's `cam` frame is the left camera's.

use nalgebra::{Isometry3, Point2, Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// One calibrated camera: a pinhole and, when it has been measured, its lens's `plumb_bob`
/// distortion (none by default). Pixels are where the lens puts light; rays are the ideal ones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinholeCamera {
    pub width: u32,
    pub height: u32,
    /// Focal lengths in pixels.
    pub fx: f64,
    pub fy: f64,
    /// Principal point in pixels.
    pub cx: f64,
    pub cy: f64,
    /// Pose of the camera in the world (maps camera coordinates to world coordinates).
    #[serde(with = "crate::pose::iso_serde")]
    pub world_from_cam: Isometry3<f64>,
    /// The lens's distortion (a calibration's; none for the renderer's own cameras).
    #[serde(default, skip_serializing_if = "crate::distortion::PlumbBob::is_none")]
    pub distortion: crate::distortion::PlumbBob,
}

impl PinholeCamera {
    /// A camera at `position` looking at `target`, with `up` appearing up in the image.
    pub fn looking_at(
        (width, height): (u32, u32),
        focal_px: f64,
        principal_point: [f64; 2],
        position: Point3<f64>,
        target: Point3<f64>,
        up: Vector3<f64>,
    ) -> Self {
        let z = (target - position).normalize();
        let x = z.cross(&up).normalize(); // image right
        let y = z.cross(&x); // image down
        let rot = nalgebra::Rotation3::from_basis_unchecked(&[x, y, z]);
        let world_from_cam =
            Isometry3::from_parts(position.coords.into(), nalgebra::UnitQuaternion::from_rotation_matrix(&rot));
        PinholeCamera {
            width,
            height,
            fx: focal_px,
            fy: focal_px,
            cx: principal_point[0],
            cy: principal_point[1],
            world_from_cam,
            distortion: Default::default(),
        }
    }

    pub fn cam_from_world(&self) -> Isometry3<f64> {
        self.world_from_cam.inverse()
    }

    /// Projects a point given in this camera's frame (through the lens, if it has a
    /// distortion); `None` behind the camera.
    pub fn project_cam(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        if p.z <= 1e-9 {
            return None;
        }
        if self.distortion.is_none() {
            return Some(Point2::new(self.fx * p.x / p.z + self.cx, self.fy * p.y / p.z + self.cy));
        }
        let (x, y) = self.distortion.distort(p.x / p.z, p.y / p.z);
        Some(Point2::new(self.fx * x + self.cx, self.fy * y + self.cy))
    }

    /// Where an ideal pinhole of the same intrinsics would image the ray the lens brings to
    /// pixel `(u, v)`: the pixel corrected for distortion (itself without one).
    pub fn undistort_px(&self, u: f64, v: f64) -> (f64, f64) {
        if self.distortion.is_none() {
            return (u, v);
        }
        let r = self.ray_cam(u, v);
        (self.fx * r.x + self.cx, self.fy * r.y + self.cy)
    }

    /// Where the lens puts the ray an ideal pinhole of the same intrinsics images at `(u, v)`.
    pub fn distort_px(&self, u: f64, v: f64) -> (f64, f64) {
        if self.distortion.is_none() {
            return (u, v);
        }
        let (x, y) = self.distortion.distort((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        (self.fx * x + self.cx, self.fy * y + self.cy)
    }

    /// Projects a world point to pixel coordinates; `None` behind the camera.
    pub fn project_world(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        self.project_cam(&self.world_from_cam.inverse_transform_point(p))
    }

    /// Direction (in the camera frame, with `z = 1`) of the ray through pixel `(u, v)` (the
    /// ray the lens brings there, if it has a distortion).
    pub fn ray_cam(&self, u: f64, v: f64) -> Vector3<f64> {
        let (xd, yd) = ((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        if self.distortion.is_none() {
            return Vector3::new(xd, yd, 1.0);
        }
        let (x, y) = self.distortion.undistort(xd, yd).unwrap_or((xd, yd));
        Vector3::new(x, y, 1.0)
    }

    /// Origin and unit direction, in the world, of the ray through pixel `(u, v)`.
    pub fn ray_world(&self, u: f64, v: f64) -> (Point3<f64>, Vector3<f64>) {
        let dir = self.world_from_cam.rotation * self.ray_cam(u, v).normalize();
        (self.world_from_cam.translation.vector.into(), dir)
    }

    /// The camera centre in the world.
    pub fn centre(&self) -> Point3<f64> {
        self.world_from_cam.translation.vector.into()
    }
}

/// A camera with a real lens: a pinhole and its `plumb_bob` distortion. Pixels are where the
/// lens puts light (distorted); rays are the ideal ones.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LensCamera {
    pub pinhole: PinholeCamera,
    pub distortion: crate::distortion::PlumbBob,
}

impl LensCamera {
    /// A pinhole with no distortion.
    pub fn ideal(pinhole: PinholeCamera) -> LensCamera {
        LensCamera { pinhole, distortion: Default::default() }
    }

    /// Where a point given in the camera's frame appears in the image; `None` behind it.
    pub fn project_cam(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        if p.z <= 1e-9 {
            return None;
        }
        let c = &self.pinhole;
        let (x, y) = self.distortion.distort(p.x / p.z, p.y / p.z);
        Some(Point2::new(c.fx * x + c.cx, c.fy * y + c.cy))
    }

    /// Where a world point appears in the image; `None` behind the camera.
    pub fn project_world(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        self.project_cam(&self.pinhole.world_from_cam.inverse_transform_point(p))
    }

    /// Origin and unit direction, in the world, of the ray the lens brings to pixel `(u, v)`.
    pub fn ray_world(&self, u: f64, v: f64) -> (Point3<f64>, Vector3<f64>) {
        let c = &self.pinhole;
        let (xd, yd) = ((u - c.cx) / c.fx, (v - c.cy) / c.fy);
        let (x, y) = self.distortion.undistort(xd, yd).unwrap_or((xd, yd));
        let dir = c.world_from_cam.rotation * Vector3::new(x, y, 1.0).normalize();
        (c.centre(), dir)
    }
}

/// The two calibrated cameras of the stereo rig. `cam` (the frame the vision pipeline reports
/// in) is the left camera's frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StereoCalibration {
    pub left: PinholeCamera,
    pub right: PinholeCamera,
}

/// Why a calibration could not be read.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    #[error("{path}: {cause}")]
    Io { path: String, cause: std::io::Error },
    #[error("{path}: line {line}, column {column}: {message}")]
    Parse { path: String, line: usize, column: usize, message: String },
    #[error("{path}: field `{field}`: {message}")]
    Invalid { path: String, field: String, message: String },
}

/// Cameras nearer than this (metres) are no stereo pair: depth from disparity would divide by
/// nearly nothing.
pub const MIN_BASELINE_M: f64 = 1e-3;

impl PinholeCamera {
    /// Checks what a camera must be to project at all: a size, finite positive focal lengths,
    /// a principal point in the image, a finite pose. Returns the field at fault (`fx`, ...).
    pub fn check(&self) -> Result<(), (String, String)> {
        if !(1..=8192).contains(&self.width) || !(1..=8192).contains(&self.height) {
            return Err(("width".into(), format!("{}x{} is no image size (1-8192 each)", self.width, self.height)));
        }
        for (name, f) in [("fx", self.fx), ("fy", self.fy)] {
            if !(f.is_finite() && f > 0.0) {
                return Err((name.into(), format!("a focal length must be positive and finite, got {f}")));
            }
        }
        for (name, c, size) in [("cx", self.cx, self.width), ("cy", self.cy, self.height)] {
            if !(c.is_finite() && (0.0..=size as f64).contains(&c)) {
                return Err((name.into(), format!("the principal point must lie in the image (0-{size}), got {c}")));
            }
        }
        if !self.world_from_cam.translation.vector.iter().all(|v| v.is_finite()) {
            return Err(("world_from_cam.translation_m".into(), "must be finite".into()));
        }
        Ok(())
    }
}

impl StereoCalibration {
    /// Maps left-camera (`cam`) coordinates to right-camera coordinates.
    pub fn right_from_left(&self) -> Isometry3<f64> {
        self.right.cam_from_world() * self.left.world_from_cam
    }

    /// The same pair in the left camera's own frame (`cam`): the left camera at the origin, the
    /// right where it stands from the left. What a camera calibration gives, and what
    /// perception assumes.
    pub fn in_left_frame(&self) -> StereoCalibration {
        StereoCalibration {
            left: PinholeCamera { world_from_cam: Isometry3::identity(), ..self.left.clone() },
            right: PinholeCamera {
                world_from_cam: self.left.cam_from_world() * self.right.world_from_cam,
                ..self.right.clone()
            },
        }
    }

    /// Distance between the two camera centres, metres.
    pub fn baseline(&self) -> f64 {
        (self.right.centre() - self.left.centre()).norm()
    }

    /// Checks that the two cameras make a stereo pair: each a camera ([`PinholeCamera::check`]),
    /// the same size, at least [`MIN_BASELINE_M`] apart. Returns the field at fault
    /// (`left.fx`, `right.width`, ...).
    pub fn check(&self) -> Result<(), (String, String)> {
        for (side, cam) in [("left", &self.left), ("right", &self.right)] {
            cam.check().map_err(|(field, message)| (format!("{side}.{field}"), message))?;
        }
        let (l, r) = (&self.left, &self.right);
        if (l.width, l.height) != (r.width, r.height) {
            return Err((
                "right.width".into(),
                format!(
                    "the left camera is {}x{} but the right {}x{}: a stereo pair must match",
                    l.width, l.height, r.width, r.height
                ),
            ));
        }
        let baseline = self.baseline();
        if !(baseline.is_finite() && baseline >= MIN_BASELINE_M) {
            return Err((
                "right.world_from_cam".into(),
                format!("the cameras are {baseline} m apart: stereo needs a baseline of at least {MIN_BASELINE_M} m"),
            ));
        }
        Ok(())
    }

    /// Reads and checks a calibration file: either a bare `{left, right}` object or a
    /// `scene.json` written by `marvin render`, whose `calibration` member is read.
    pub fn load(path: &Path) -> Result<Self, CalibrationError> {
        let shown = path.display().to_string();
        let text =
            std::fs::read_to_string(path).map_err(|cause| CalibrationError::Io { path: shown.clone(), cause })?;
        let calib = Self::from_json(&text).map_err(|e| CalibrationError::Parse {
            path: shown.clone(),
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
        calib.check().map_err(|(field, message)| CalibrationError::Invalid { path: shown, field, message })?;
        Ok(calib)
    }

    /// Parses a bare calibration or a scene file's `calibration` member.
    pub fn from_json(text: &str) -> Result<Self, serde_json::Error> {
        #[derive(Deserialize)]
        struct SceneFile {
            calibration: StereoCalibration,
        }
        // Decide by shape rather than with an untagged enum, whose errors hide the real cause.
        let value: serde_json::Value = serde_json::from_str(text)?;
        if value.get("calibration").is_some() {
            Ok(serde_json::from_value::<SceneFile>(value)?.calibration)
        } else {
            serde_json::from_value(value)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> PinholeCamera {
        PinholeCamera::looking_at(
            (512, 512),
            1000.0,
            [255.5, 255.5],
            Point3::new(-0.1, -0.7, 0.6),
            Point3::origin(),
            Vector3::z(),
        )
    }

    #[test]
    fn target_projects_to_principal_point() {
        let cam = camera();
        let p = cam.project_world(&Point3::origin()).unwrap();
        assert!((p - Point2::new(255.5, 255.5)).norm() < 1e-9);
    }

    #[test]
    fn world_up_appears_up_and_right_appears_right() {
        let cam = camera();
        let up = cam.project_world(&Point3::new(0.0, 0.0, 0.05)).unwrap();
        assert!(up.y < 255.5, "world up should move up the image: {up}");
        let right = cam.project_world(&Point3::new(0.05, 0.0, 0.0)).unwrap();
        assert!(right.x > 255.5, "world +x seen from -y should be image right: {right}");
    }

    #[test]
    fn ray_through_a_projection_passes_through_the_point() {
        let cam = camera();
        let p = Point3::new(0.03, 0.07, 0.02);
        let px = cam.project_world(&p).unwrap();
        let (o, d) = cam.ray_world(px.x, px.y);
        let to_p = p - o;
        assert!((to_p - d * to_p.dot(&d)).norm() < 1e-9);
    }

    #[test]
    fn a_lens_camera_projects_by_the_plumb_bob_formula_and_casts_rays_back() {
        let lens = crate::distortion::PlumbBob { k1: -0.2, k2: 0.09, p1: 3e-4, p2: -2e-4, k3: 0.0 };
        let cam = LensCamera { pinhole: camera(), distortion: lens };
        let p = Point3::new(0.12, 0.09, 0.01);
        let q = cam.pinhole.world_from_cam.inverse_transform_point(&p);
        // The formula written out: x' = x (1 + k1 r² + k2 r⁴) + 2 p1 x y + p2 (r² + 2 x²), ...
        let (x, y) = (q.x / q.z, q.y / q.z);
        let r2 = x * x + y * y;
        let radial = 1.0 + lens.k1 * r2 + lens.k2 * r2 * r2;
        let xd = x * radial + 2.0 * lens.p1 * x * y + lens.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + lens.p1 * (r2 + 2.0 * y * y) + 2.0 * lens.p2 * x * y;
        let px = cam.project_world(&p).unwrap();
        assert!((px.x - (1000.0 * xd + 255.5)).abs() < 0.01 && (px.y - (1000.0 * yd + 255.5)).abs() < 0.01);
        let (o, d) = cam.ray_world(px.x, px.y);
        let to_p = p - o;
        assert!((to_p - d * to_p.dot(&d)).norm() < 1e-9);
    }

    #[test]
    fn calibration_round_trips_through_json() {
        let calib = StereoCalibration { left: camera(), right: camera() };
        let text = serde_json::to_string(&calib).unwrap();
        assert_eq!(StereoCalibration::from_json(&text).unwrap(), calib);
        let scene = format!("{{\"calibration\": {text}, \"objects\": []}}");
        assert_eq!(StereoCalibration::from_json(&scene).unwrap(), calib);
        assert!(StereoCalibration::from_json("{\"left\": 3}").is_err());
    }
}
