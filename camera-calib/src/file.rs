//! The calibration files: the project's JSON (`cameras.json`: both cameras, the rig, standard
//! deviations, the covariance, the fit) and a ROS `camera_info` YAML per camera (`left.yaml`,
//! `right.yaml`: `plumb_bob`, K, D, and R, P of the stereo rectification), as ROS's
//! `camera_calibration` writes them.

use crate::camera::{INTRINSIC_NAMES, Intrinsics};
use crate::solve::StereoSolution;
use nalgebra::{Isometry3, Matrix3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The JSON's format tag.
pub const FORMAT: &str = "marvin-cameras/1";

/// One camera in the JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraEntry {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// `[k1, k2, p1, p2, k3]`, ROS's order.
    pub distortion: [f64; 5],
    /// Standard deviations of `fx fy cx cy k1 k2 p1 p2 k3` (0 for a parameter held fixed).
    pub sigma: [f64; 9],
    pub rms_px: f64,
}

impl CameraEntry {
    pub fn intrinsics(&self) -> Intrinsics {
        Intrinsics {
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
            distortion: mesh::distortion::PlumbBob::from_d(self.distortion),
        }
    }
}

/// A pose in the JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseEntry {
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}

impl PoseEntry {
    pub fn of(p: &Isometry3<f64>) -> PoseEntry {
        let (t, q) = (p.translation.vector, p.rotation.coords);
        PoseEntry { translation_m: [t.x, t.y, t.z], rotation_xyzw: [q.x, q.y, q.z, q.w] }
    }

    pub fn isometry(&self) -> Isometry3<f64> {
        let [x, y, z, w] = self.rotation_xyzw;
        Isometry3::from_parts(
            Translation3::from(Vector3::from(self.translation_m)),
            UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
        )
    }
}

/// The project's calibration file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CamerasFile {
    pub format: String,
    pub width: u32,
    pub height: u32,
    pub left: CameraEntry,
    pub right: CameraEntry,
    /// The right camera's pose in the left's frame (x right, y down, z along the axis).
    pub right_from_left: PoseEntry,
    /// Standard deviations of `right_from_left`: rotation vector (radians), translation (metres).
    pub right_from_left_sigma: [f64; 6],
    /// Reprojection RMS over every corner, pixels.
    pub rms_px: f64,
    /// Names of the covariance's rows: both cameras' intrinsics, then `right_from_left`.
    pub covariance_order: Vec<String>,
    /// The covariance of those 24 parameters, row by row.
    pub covariance: Vec<Vec<f64>>,
}

/// Why a calibration file could not be read; names the file.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct FileError {
    pub path: String,
    pub message: String,
}

impl CamerasFile {
    pub fn from_solution(s: &StereoSolution, size: [u32; 2]) -> CamerasFile {
        let entry = |k: &Intrinsics, sigma: &[f64; 9], rms: f64| CameraEntry {
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            distortion: k.distortion.d(),
            sigma: *sigma,
            rms_px: rms,
        };
        let order = ["left", "right"]
            .iter()
            .flat_map(|c| INTRINSIC_NAMES.iter().map(move |n| format!("{c}.{n}")))
            .chain(["rx", "ry", "rz", "tx", "ty", "tz"].iter().map(|n| format!("right_from_left.{n}")))
            .collect();
        CamerasFile {
            format: FORMAT.into(),
            width: size[0],
            height: size[1],
            left: entry(&s.left, &s.left_sigma, s.left_rms_px),
            right: entry(&s.right, &s.right_sigma, s.right_rms_px),
            right_from_left: PoseEntry::of(&s.right_from_left),
            right_from_left_sigma: s.rig_sigma,
            rms_px: s.rms_px,
            covariance_order: order,
            covariance: s.covariance.row_iter().map(|r| r.iter().copied().collect()).collect(),
        }
    }

    /// The pair as vision takes it: the left camera at the origin of `cam`, the right where
    /// the calibration puts it, each with its lens.
    pub fn stereo_calibration(&self) -> mesh::StereoCalibration {
        let camera = |c: &CameraEntry, world_from_cam: Isometry3<f64>| mesh::PinholeCamera {
            width: self.width,
            height: self.height,
            fx: c.fx,
            fy: c.fy,
            cx: c.cx,
            cy: c.cy,
            world_from_cam,
            distortion: mesh::distortion::PlumbBob::from_d(c.distortion),
        };
        mesh::StereoCalibration {
            left: camera(&self.left, Isometry3::identity()),
            right: camera(&self.right, self.right_from_left.isometry().inverse()),
        }
    }

    /// Reads `cameras.json`, naming the file and the field at fault.
    pub fn load(path: &Path) -> Result<CamerasFile, FileError> {
        let err = |message: String| FileError { path: path.display().to_string(), message };
        let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
        let de = &mut serde_json::Deserializer::from_str(&text);
        let file: CamerasFile =
            serde_path_to_error::deserialize(de).map_err(|e| err(format!("{}: {}", e.path(), e.inner())))?;
        if file.format != FORMAT {
            return Err(err(format!("format: `{}` is not `{FORMAT}`", file.format)));
        }
        Ok(file)
    }

    /// Writes `cameras.json`, `left.yaml` and `right.yaml` into `dir`.
    pub fn save_all(&self, dir: &Path) -> std::io::Result<()> {
        std::fs::create_dir_all(dir)?;
        std::fs::write(dir.join("cameras.json"), serde_json::to_string_pretty(self)? + "\n")?;
        let [left, right] = self.ros_yaml();
        std::fs::write(dir.join("left.yaml"), left)?;
        std::fs::write(dir.join("right.yaml"), right)
    }

    /// The rectification: each camera's `R` (its frame to the common rectified frame) and the
    /// rectified cameras' `P`, as ROS's `camera_info` gives them. The rectified frame's x runs
    /// along the baseline from the left camera to the right; its z is the mean of the two
    /// optical axes, made perpendicular; both share the focal length (the four focal lengths'
    /// least, so no pixel is magnified) and the left's principal point.
    pub fn rectification(&self) -> ([Matrix3<f64>; 2], [[f64; 12]; 2]) {
        let right_from_left = self.right_from_left.isometry();
        let left_from_right = right_from_left.inverse();
        let baseline = left_from_right.translation.vector;
        let e1 = baseline.normalize();
        let mean_axis = (Vector3::z() + left_from_right.rotation * Vector3::z()).normalize();
        let e2 = mean_axis.cross(&e1).normalize();
        let e3 = e1.cross(&e2);
        let rect_from_left = Matrix3::from_rows(&[e1.transpose(), e2.transpose(), e3.transpose()]);
        let rect_from_right = rect_from_left * left_from_right.rotation.to_rotation_matrix().into_inner();
        let f = [self.left.fx, self.left.fy, self.right.fx, self.right.fy].into_iter().fold(f64::MAX, f64::min);
        let (cx, cy) = (self.left.cx, self.left.cy);
        let p = |tx: f64| [f, 0.0, cx, tx, 0.0, f, cy, 0.0, 0.0, 0.0, 1.0, 0.0];
        ([rect_from_left, rect_from_right], [p(0.0), p(-f * baseline.norm())])
    }

    /// The two ROS `camera_info` YAML files' text: left, right.
    pub fn ros_yaml(&self) -> [String; 2] {
        let (r, p) = self.rectification();
        [("left", &self.left, 0), ("right", &self.right, 1)].map(|(name, c, k)| {
            let matrix = |rows: usize, cols: usize, data: &[f64]| {
                let d: Vec<String> = data.iter().map(|x| yaml_float(*x)).collect();
                format!("\n  rows: {rows}\n  cols: {cols}\n  data: [{}]", d.join(", "))
            };
            let kmat = [c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0];
            let rmat: Vec<f64> = r[k].transpose().iter().copied().collect();
            format!(
                "image_width: {}\nimage_height: {}\ncamera_name: {name}\ncamera_matrix:{}\ndistortion_model: plumb_bob\ndistortion_coefficients:{}\nrectification_matrix:{}\nprojection_matrix:{}\n",
                self.width,
                self.height,
                matrix(3, 3, &kmat),
                matrix(1, 5, &c.distortion),
                matrix(3, 3, &rmat),
                matrix(3, 4, &p[k]),
            )
        })
    }
}

/// A float as YAML 1.1 readers (PyYAML among them) take one: a point in the mantissa and a
/// signed exponent (`1.5e+2`, not `1.5e2`, which they read as a string).
fn yaml_float(x: f64) -> String {
    let s = format!("{x:.12e}");
    match s.split_once('e') {
        Some((m, e)) if !e.starts_with('-') => format!("{m}e+{e}"),
        _ => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::tests::{SIZE, boards, views};
    use crate::{Board, Options, calibrate_stereo};
    use nalgebra::Point3;

    fn file() -> CamerasFile {
        let s = calibrate_stereo(&Board::LIBRARY, SIZE, &views(&boards(), 0.05, 5), &Options::default()).unwrap();
        CamerasFile::from_solution(&s, SIZE)
    }

    #[test]
    fn the_json_comes_back_as_written_and_bad_fields_are_named() {
        let f = file();
        let dir = std::env::temp_dir().join(format!("marvin_cameras_{}", std::process::id()));
        f.save_all(&dir).unwrap();
        // serde_json reads floats back to within the last bit.
        let back = CamerasFile::load(&dir.join("cameras.json")).unwrap();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * a.abs().max(1.0);
        for (a, b) in [(&back.left, &f.left), (&back.right, &f.right)] {
            assert!(a.intrinsics().to_params().iter().zip(b.intrinsics().to_params()).all(|(x, y)| close(*x, y)));
        }
        let (a, b) = (back.right_from_left.isometry(), f.right_from_left.isometry());
        assert!(
            (a.translation.vector - b.translation.vector).norm() < 1e-12 && a.rotation.angle_to(&b.rotation) < 1e-9
        );
        assert_eq!((back.covariance.len(), back.covariance_order.len()), (24, 24));
        let text = std::fs::read_to_string(dir.join("cameras.json")).unwrap().replace("\"fx\"", "\"focal\"");
        std::fs::write(dir.join("bad.json"), text).unwrap();
        let e = CamerasFile::load(&dir.join("bad.json")).unwrap_err().to_string();
        assert!(e.contains("bad.json") && e.contains("left"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Parses a `rows/cols/data` block of the YAML text.
    fn block(yaml: &str, key: &str) -> Vec<f64> {
        let at = yaml.find(&format!("{key}:")).unwrap();
        let data = &yaml[at..];
        let open = data.find('[').unwrap();
        let close = data.find(']').unwrap();
        data[open + 1..close].split(',').map(|x| x.trim().parse().unwrap()).collect()
    }

    #[test]
    fn the_ros_files_rectify_a_point_onto_one_row() {
        let f = file();
        let [left, right] = f.ros_yaml();
        assert!(left.contains("distortion_model: plumb_bob") && left.contains("image_width: 512"));
        let project = |yaml: &str, cam_point: Point3<f64>| {
            let r = block(yaml, "rectification_matrix");
            let p = block(yaml, "projection_matrix");
            let r = Matrix3::from_row_slice(&r);
            let p = nalgebra::Matrix3x4::from_row_slice(&p);
            let q = p * (r * cam_point.coords).push(1.0);
            (q.x / q.z, q.y / q.z)
        };
        let in_left = Point3::new(0.07, -0.05, 0.8);
        let in_right = f.right_from_left.isometry() * in_left;
        let (ul, vl) = project(&left, in_left);
        let (ur, vr) = project(&right, in_right);
        assert!((vl - vr).abs() < 1e-6, "rows {vl} and {vr}");
        // Disparity f B / Z along the rectified axis.
        let k = block(&left, "camera_matrix");
        assert!(ul > ur && k[0] > 900.0, "left {ul}, right {ur}");
    }
}
