//! Zhang's closed-form start ("A flexible new technique for camera calibration", 2000): a
//! homography per view from the board's plane to the image (normalised DLT), the camera
//! matrix from the homographies' constraints on the image of the absolute conic (no skew),
//! then each view's board pose. Distortion is taken as none here: the adjustment
//! ([`crate::adjust`]) brings it in.

use crate::camera::Intrinsics;
use nalgebra::{DMatrix, Isometry3, Matrix3, Point2, Rotation3, Translation3, UnitQuaternion, Vector3};

/// The unit vector of `m`'s null space: the eigenvector of `mᵀm` of least eigenvalue.
fn null_vector(m: &DMatrix<f64>) -> nalgebra::DVector<f64> {
    let eig = (m.transpose() * m).symmetric_eigen();
    let k = eig.eigenvalues.iamin();
    eig.eigenvectors.column(k).into_owned()
}

/// Translation and scale that centre points on their mean at an average distance of sqrt 2
/// (Hartley's normalisation), as a matrix.
fn normaliser(points: &[Point2<f64>]) -> Matrix3<f64> {
    let n = points.len() as f64;
    let mean = points.iter().fold(Vector3::zeros(), |a, p| a + Vector3::new(p.x, p.y, 0.0)) / n;
    let spread = points.iter().map(|p| (p.x - mean.x).hypot(p.y - mean.y)).sum::<f64>() / n;
    let s = std::f64::consts::SQRT_2 / spread.max(1e-12);
    Matrix3::new(s, 0.0, -s * mean.x, 0.0, s, -s * mean.y, 0.0, 0.0, 1.0)
}

/// The homography taking board-plane points `(x, y)` to pixels, by the normalised DLT;
/// `None` for fewer than 4 points or a degenerate set.
pub fn homography(plane: &[Point2<f64>], image: &[Point2<f64>]) -> Option<Matrix3<f64>> {
    if plane.len() < 4 || plane.len() != image.len() {
        return None;
    }
    let (tp, ti) = (normaliser(plane), normaliser(image));
    let mut a = DMatrix::zeros(2 * plane.len(), 9);
    for (k, (p, q)) in plane.iter().zip(image).enumerate() {
        let p = tp * p.to_homogeneous();
        let q = ti * q.to_homogeneous();
        let (x, y, u, v) = (p.x / p.z, p.y / p.z, q.x / q.z, q.y / q.z);
        a.row_mut(2 * k).copy_from_slice(&[-x, -y, -1.0, 0.0, 0.0, 0.0, u * x, u * y, u]);
        a.row_mut(2 * k + 1).copy_from_slice(&[0.0, 0.0, 0.0, -x, -y, -1.0, v * x, v * y, v]);
    }
    let h = null_vector(&a);
    let hn = Matrix3::new(h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7], h[8]);
    let h = ti.try_inverse()? * hn * tp;
    (h[(2, 2)].abs() > 1e-15).then(|| h / h[(2, 2)])
}

/// The camera matrix from two or more views' homographies (no skew). `None` when the
/// homographies do not determine it (all boards parallel, or too few).
pub fn intrinsics(homographies: &[Matrix3<f64>]) -> Option<Intrinsics> {
    if homographies.len() < 2 {
        return None;
    }
    // b = [B11, B22, B13, B23, B33] of B = K^-T K^-1 (B12 = 0: no skew).
    let v = |h: &Matrix3<f64>, i: usize, j: usize| {
        let (a, b) = (h.column(i), h.column(j));
        [a[0] * b[0], a[1] * b[1], a[0] * b[2] + a[2] * b[0], a[1] * b[2] + a[2] * b[1], a[2] * b[2]]
    };
    let mut m = DMatrix::zeros(2 * homographies.len(), 5);
    for (k, h) in homographies.iter().enumerate() {
        // Scale each view's rows alike, whatever its homography's scale.
        let h = h / h.column(0).norm().max(h.column(1).norm());
        let (v12, v11, v22) = (v(&h, 0, 1), v(&h, 0, 0), v(&h, 1, 1));
        m.row_mut(2 * k).copy_from_slice(&v12);
        let diff: Vec<f64> = v11.iter().zip(&v22).map(|(a, b)| a - b).collect();
        m.row_mut(2 * k + 1).copy_from_slice(&diff);
    }
    let mut b = null_vector(&m);
    if b[0] < 0.0 {
        b = -b;
    }
    let (b11, b22, b13, b23, b33) = (b[0], b[1], b[2], b[3], b[4]);
    if b11 <= 0.0 || b22 <= 0.0 {
        return None;
    }
    let (cx, cy) = (-b13 / b11, -b23 / b22);
    let s = b33 - cx * cx * b11 - cy * cy * b22;
    (s > 0.0).then(|| Intrinsics::pinhole((s / b11).sqrt(), (s / b22).sqrt(), cx, cy))
}

/// A view's board pose (`cam_from_board`) from its homography and the camera matrix: the board
/// in front of the camera, its rotation the nearest to the homography's columns.
pub fn board_pose(h: &Matrix3<f64>, k: &Matrix3<f64>) -> Option<Isometry3<f64>> {
    let m = k.try_inverse()? * h;
    let scale = 1.0 / m.column(0).norm();
    let sign = if m[(2, 2)] * scale < 0.0 { -1.0 } else { 1.0 };
    let (r1, r2, t) = (m.column(0) * scale * sign, m.column(1) * scale * sign, m.column(2) * scale * sign);
    let r = Matrix3::from_columns(&[r1, r2, r1.cross(&r2)]);
    let svd = r.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let mut nearest = u * vt;
    if nearest.determinant() < 0.0 {
        nearest = u * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, -1.0)) * vt;
    }
    let rotation = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(nearest));
    Some(Isometry3::from_parts(Translation3::from(t.into_owned()), rotation))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::Board;
    use nalgebra::Point3;

    fn views() -> Vec<Isometry3<f64>> {
        [(0.3, -0.2, 0.1), (-0.4, 0.1, -0.3), (0.1, 0.5, 0.6), (-0.2, -0.4, 1.2)]
            .iter()
            .enumerate()
            .map(|(k, &(a, b, c))| {
                Isometry3::from_parts(
                    Translation3::new(-0.05 + 0.02 * k as f64, -0.04, 0.7 + 0.05 * k as f64),
                    UnitQuaternion::from_euler_angles(a, b, c),
                )
            })
            .collect()
    }

    #[test]
    fn exact_views_give_back_the_camera_and_the_poses() {
        let cam = Intrinsics::pinhole(1010.0, 1005.0, 251.0, 262.0);
        let board = Board::LIBRARY;
        let plane: Vec<Point2<f64>> = board.points().iter().map(|p| Point2::new(p.x, p.y)).collect();
        let poses = views();
        let hs: Vec<Matrix3<f64>> = poses
            .iter()
            .map(|pose| {
                let image: Vec<Point2<f64>> =
                    board.points().iter().map(|p| cam.project(&(pose * p)).unwrap()).collect();
                homography(&plane, &image).unwrap()
            })
            .collect();
        let k = intrinsics(&hs).unwrap();
        for (a, b) in k.to_params().iter().zip(cam.to_params()) {
            assert!((a - b).abs() < 1e-6, "{:?} vs {:?}", k, cam);
        }
        for (h, pose) in hs.iter().zip(&poses) {
            let got = board_pose(h, &cam.k()).unwrap();
            assert!((got.translation.vector - pose.translation.vector).norm() < 1e-9);
            assert!(got.rotation.angle_to(&pose.rotation) < 1e-9);
            let p = Point3::new(0.1, 0.05, 0.0);
            assert!((got * p - pose * p).norm() < 1e-9);
        }
    }

    #[test]
    fn parallel_boards_do_not_determine_the_camera() {
        let cam = Intrinsics::pinhole(1000.0, 1000.0, 256.0, 256.0);
        let board = Board::LIBRARY;
        let plane: Vec<Point2<f64>> = board.points().iter().map(|p| Point2::new(p.x, p.y)).collect();
        let hs: Vec<Matrix3<f64>> = (0..4)
            .map(|k| {
                let pose = Isometry3::translation(-0.05 + 0.03 * k as f64, -0.04, 0.7);
                let image: Vec<Point2<f64>> =
                    board.points().iter().map(|p| cam.project(&(pose * p)).unwrap()).collect();
                homography(&plane, &image).unwrap()
            })
            .collect();
        let k = intrinsics(&hs);
        assert!(k.is_none_or(|k| (k.fx - 1000.0).abs() > 1.0), "fronto-parallel views gave {k:?}");
    }
}
