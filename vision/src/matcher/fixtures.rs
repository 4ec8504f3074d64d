//! What the matcher's unit tests set up alike.

use super::model::MatcherModel;
use nalgebra::{Isometry3, Point3, Vector3};

pub(crate) use crate::front_end::rectify::tests::camera_at;

/// A library model as the matcher holds it.
pub(crate) fn model(name: &str) -> MatcherModel {
    let lib = mesh::Library::load_default().unwrap();
    MatcherModel::from_model(lib.get(name).unwrap_or_else(|| panic!("no model `{name}` in the library")))
}

/// A report of `model` at `pose` (`cam`) on no 3D evidence, fully borne out in the image.
pub(crate) fn report(model: &MatcherModel, pose: Isometry3<f64>) -> crate::matcher::Located {
    crate::matcher::Located {
        model: model.name.clone(),
        cam_from_model: pose,
        support: 0.0,
        support_fraction: 0.0,
        scene_lines: Vec::new(),
        image_support: 1.0,
        grasps: Vec::new(),
    }
}

/// The mean albedo of a library model's faces: how the fixtures draw it (the matcher itself
/// does not know a part's material).
pub(crate) fn albedo(name: &str) -> f64 {
    let lib = mesh::Library::load_default().unwrap();
    let mesh = &lib.get(name).unwrap_or_else(|| panic!("no model `{name}` in the library")).mesh;
    mesh.albedo.iter().map(|a| *a as f64).sum::<f64>() / mesh.albedo.len().max(1) as f64
}

/// A 512 x 512 image of `objects` (models at poses in the `cam` frame) against a uniform
/// `background`, by casting a ray through each pixel centre, a face of normal `n` (`cam`)
/// showing `shade(n)` grey levels per unit albedo (a light's prediction: taken as a function,
/// so that the fixtures import none of the modules whose tests use them). No other code of
/// the crate's draws it.
pub(crate) fn render(
    cam: &mesh::PinholeCamera,
    objects: &[(&MatcherModel, Isometry3<f64>)],
    shade: &dyn Fn(&Vector3<f64>) -> f64,
    background: u8,
) -> crate::image::GreyImage {
    let faces: Vec<([Point3<f64>; 3], f64)> = objects
        .iter()
        .flat_map(|(m, pose)| m.triangles.iter().map(move |t| (t.map(|p| pose * p), albedo(&m.name))))
        .collect();
    let mut pixels = vec![background; 512 * 512];
    for (i, px) in pixels.iter_mut().enumerate() {
        let d = cam.ray_cam((i % 512) as f64, (i / 512) as f64);
        let nearest = faces
            .iter()
            .filter_map(|(t, albedo)| Some((mesh::trimesh::ray_triangle(&Point3::origin(), &d, t)?, t, albedo)))
            .filter(|(s, _, _)| *s > 0.0)
            .min_by(|a, b| a.0.total_cmp(&b.0));
        if let Some((_, t, albedo)) = nearest {
            let n = (t[1] - t[0]).cross(&(t[2] - t[0])).normalize();
            *px = (albedo * shade(&n)).round().clamp(0.0, 255.0) as u8;
        }
    }
    crate::image::GreyImage::new(512, 512, pixels).unwrap()
}

/// A verged pair of 512 x 512 cameras 0.2 m apart, 0.7 m from the origin they look at, z up.
pub(crate) fn verged_pair() -> (mesh::PinholeCamera, mesh::PinholeCamera) {
    let cam = |x: f64| {
        mesh::PinholeCamera::looking_at(
            (512, 512),
            1000.0,
            [255.5, 255.5],
            nalgebra::Point3::new(x, -0.55, 0.45),
            nalgebra::Point3::origin(),
            Vector3::z(),
        )
    };
    (cam(-0.1), cam(0.1))
}

/// Whether every line of `model` at `got` lies on one of its lines at `truth`, ends within
/// `tolerance` (metres): the same pose up to the model's symmetry.
pub(crate) fn on_its_lines(model: &MatcherModel, got: &Isometry3<f64>, truth: &Isometry3<f64>, tolerance: f64) -> bool {
    model.lines.iter().all(|l| {
        let (a, b) = (got * l.a, got * l.b);
        model.lines.iter().any(|m| {
            let (ma, mb) = (truth * m.a, truth * m.b);
            ((ma - a).norm() < tolerance && (mb - b).norm() < tolerance)
                || ((ma - b).norm() < tolerance && (mb - a).norm() < tolerance)
        })
    })
}

/// A tiny deterministic generator, so the test needs no RNG crate.
pub(crate) struct Lcg(pub u64);
impl Lcg {
    pub(crate) fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    pub(crate) fn noise(&mut self, s: f64) -> Vector3<f64> {
        Vector3::new(self.next() - 0.5, self.next() - 0.5, self.next() - 0.5) * 2.0 * s
    }
}
