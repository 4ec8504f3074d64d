//! Ground truth for evaluation code only: exact ray casts into the settled scene's triangles,
//! and [`AskTruth`], the robot server's evaluation-only request.

use mesh::{LensCamera, StereoCalibration, TriMesh};
use nalgebra::{Point3, Vector3};
use vision::front_end::rectify::Rectification;

/// The scene's surfaces as world-space triangles.
pub struct TruthScene {
    triangles: Vec<[Point3<f64>; 3]>,
}

impl TruthScene {
    pub fn new(meshes: impl IntoIterator<Item = TriMesh>) -> TruthScene {
        let mut triangles = Vec::new();
        for m in meshes {
            triangles.extend((0..m.triangles.len()).map(|t| m.corners(t)));
        }
        TruthScene { triangles }
    }

    /// Nearest hit of the ray `o + t d`: distance and triangle.
    pub fn cast(&self, o: &Point3<f64>, d: &Vector3<f64>) -> Option<(f64, usize)> {
        let mut best: Option<(f64, usize)> = None;
        for (i, triangle) in self.triangles.iter().enumerate() {
            let Some(t) = mesh::trimesh::ray_triangle(o, d, triangle) else { continue };
            if t > 0.0 && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, i));
            }
        }
        best
    }

    /// Where the ray through left pixel `(x, y)` meets the nearer of the surfaces on either side
    /// of an edge with gradient direction `orientation` there: the plane of the nearest surface
    /// hit half a pixel to a pixel either side, intersected with the ray itself.
    pub fn edge_point(&self, cam: &LensCamera, x: f64, y: f64, orientation: f64) -> Option<Point3<f64>> {
        let (s, c) = orientation.sin_cos();
        let (o, centre_dir) = cam.ray_world(x, y);
        let mut nearest: Option<(f64, usize)> = None;
        for k in [-1.0, -0.5, 0.0, 0.5, 1.0] {
            let (_, d) = cam.ray_world(x + k * c, y + k * s);
            if let Some((t, tri)) = self.cast(&o, &d) {
                let depth = t * d.dot(&(cam.pinhole.world_from_cam.rotation * Vector3::z()));
                if nearest.is_none_or(|(nd, _)| depth < nd) {
                    nearest = Some((depth, tri));
                }
            }
        }
        let [a, b, cc] = self.triangles[nearest?.1];
        let n = (b - a).cross(&(cc - a));
        let denom = n.dot(&centre_dir);
        if denom.abs() < 1e-12 {
            return None;
        }
        Some(o + centre_dir * (n.dot(&(a - o)) / denom))
    }

    /// The true disparity at a left edgel (the nearer surface's at an occluding boundary), in
    /// the rectified frame of the calibration vision was given (`rect`): the point the true
    /// left camera sees at the edgel, where the true right camera sees it, both rectified.
    pub fn disparity(&self, cams: &EvalCameras, rect: &Rectification, x: f64, y: f64, orientation: f64) -> Option<f64> {
        use vision::front_end::rectify::Side;
        let p = self.edge_point(&cams.true_left, x, y, orientation)?;
        let right = cams.true_right.project_world(&p)?;
        let (left_rect, _) = rect.to_rectified(Side::Left, x, y);
        let (right_rect, _) = rect.to_rectified(Side::Right, right.x, right.y);
        Some(left_rect - right_rect)
    }
}

/// The cameras an evaluation compares: the calibration vision was given (its `cam` frame is
/// that left camera's), and the true cameras (as built, with their lenses) through which the
/// truth is seen. In the ideal preset they are the same cameras.
#[derive(Debug, Clone)]
pub struct EvalCameras {
    pub vision: StereoCalibration,
    pub true_left: LensCamera,
    pub true_right: LensCamera,
}

impl EvalCameras {
    /// Vision given the cell's nominal calibration, the truth as built.
    pub fn of(imaging: &sim::imaging::Imaging) -> EvalCameras {
        EvalCameras {
            vision: imaging.nominal.clone(),
            true_left: imaging.rig.left.lens_camera(),
            true_right: imaging.rig.right.lens_camera(),
        }
    }

    /// Vision given measured cameras (a camera calibration's, lenses included), placed in the
    /// world where the left camera truly stands. Vision's `cam` frame is that camera's (its
    /// images are); where it stands in the cell is the hand-eye calibration's to measure, and
    /// `marvin run` uses that measurement. Placed where the world file draws it instead, every
    /// report would carry the mounting's 2 mm and 0.15 deg, which vision cannot see.
    pub fn measured(imaging: &sim::imaging::Imaging, measured: &StereoCalibration) -> EvalCameras {
        let truly = EvalCameras::of(imaging);
        EvalCameras::measured_at(measured, truly.true_left, truly.true_right)
    }

    /// [`EvalCameras::measured`] for cameras as built given directly (a scene.json's).
    pub fn measured_at(measured: &StereoCalibration, true_left: LensCamera, true_right: LensCamera) -> EvalCameras {
        let world_from_left = true_left.pinhole.world_from_cam;
        let mut vision = measured.clone();
        vision.left.world_from_cam = world_from_left * measured.left.world_from_cam;
        vision.right.world_from_cam = world_from_left * measured.right.world_from_cam;
        EvalCameras { vision, true_left, true_right }
    }

    /// Vision given the true pinholes exactly (no lens, as the ideal cell has).
    pub fn exact(calib: &StereoCalibration) -> EvalCameras {
        EvalCameras {
            vision: calib.clone(),
            true_left: LensCamera::ideal(calib.left.clone()),
            true_right: LensCamera::ideal(calib.right.clone()),
        }
    }
}

/// The robot server's `truth` request (served only with `--truth`, to evaluation). It is not a
/// method of the client itself, so code on the run path cannot ask without taking this in.
pub trait AskTruth {
    fn truth(&mut self) -> Result<crate::protocol::TruthReply, crate::engine::client::ClientError>;
}

impl AskTruth for crate::engine::client::Client {
    fn truth(&mut self) -> Result<crate::protocol::TruthReply, crate::engine::client::ClientError> {
        self.call(&crate::protocol::Request::Truth {})
    }
}
