//! What the matcher's unit tests set up alike.

use super::model::MatcherModel;
use nalgebra::{Isometry3, Vector3};

pub(crate) use crate::front_end::rectify::tests::camera_at;

/// A library model as the matcher holds it.
pub(crate) fn model(name: &str) -> MatcherModel {
    let lib = mesh::Library::load_default().unwrap();
    MatcherModel::from_model(lib.get(name).unwrap_or_else(|| panic!("no model `{name}` in the library")))
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
