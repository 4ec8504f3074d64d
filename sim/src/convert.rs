//! The one place where the project's nalgebra (f64) geometry meets rapier's glam (f32) types.

use nalgebra::{Isometry3, Matrix3, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};
use rapier3d::math::{Matrix, Pose, Rotation, Vector};

pub fn vector(v: &Vector3<f64>) -> Vector {
    Vector::new(v.x as f32, v.y as f32, v.z as f32)
}

pub fn point(p: &Point3<f64>) -> Vector {
    vector(&p.coords)
}

pub fn pose(iso: &Isometry3<f64>) -> Pose {
    let q = iso.rotation.quaternion();
    let rotation = Rotation::from_xyzw(q.i as f32, q.j as f32, q.k as f32, q.w as f32).normalize();
    Pose::from_parts(vector(&iso.translation.vector), rotation)
}

pub fn iso(pose: &Pose) -> Isometry3<f64> {
    let (t, q) = (pose.translation, pose.rotation);
    let rotation = UnitQuaternion::from_quaternion(Quaternion::new(q.w as f64, q.x as f64, q.y as f64, q.z as f64));
    Isometry3::from_parts(Translation3::new(t.x as f64, t.y as f64, t.z as f64), rotation)
}

pub fn matrix(m: &Matrix3<f64>) -> Matrix {
    // glam matrices are column-major: from_cols takes columns.
    let col = |j: usize| vector(&m.column(j).into_owned());
    Matrix::from_cols(col(0), col(1), col(2))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_round_trip_and_act_alike() {
        let iso0 = mesh::pose::from_position_rpy_deg([0.1, -0.2, 0.3], [30.0, 40.0, -50.0]);
        let p = Point3::new(0.01, 0.02, -0.03);
        let moved_na = iso0 * p;
        let moved_glam = pose(&iso0).transform_point(point(&p));
        assert!((moved_na - Point3::new(moved_glam.x as f64, moved_glam.y as f64, moved_glam.z as f64)).norm() < 1e-6);
        let back = iso(&pose(&iso0));
        assert!((back.to_homogeneous() - iso0.to_homogeneous()).norm() < 1e-6);
    }

    #[test]
    fn matrices_keep_rows_and_columns() {
        let m = Matrix3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0);
        let g = matrix(&m);
        let v = Vector3::new(1.0, -1.0, 0.5);
        let (a, b) = (m * v, g * vector(&v));
        assert!((a - Vector3::new(b.x as f64, b.y as f64, b.z as f64)).norm() < 1e-5);
    }
}
