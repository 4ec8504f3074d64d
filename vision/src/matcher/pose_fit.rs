//! Least-squares pose from 3D line correspondences, as the matcher of Pollard, Porrill, Mayhew &
//! Frisby takes it from Faugeras & Hebert: the rotation from line directions by the quaternion
//! method (the unit quaternion maximising the weighted agreement of rotated model directions with
//! scene directions is the top eigenvector of a symmetric 4x4 matrix), then the translation from
//! line positions by linear least squares (each scene point pulled onto its model line).

use nalgebra::{Isometry3, Matrix3, Matrix4, Point3, Quaternion, Translation3, UnitQuaternion, Vector3};

/// A model direction paired with a scene direction (both unit, signs already agreed), weighted.
#[derive(Debug, Clone, Copy)]
pub struct DirectionPair {
    pub model: Vector3<f64>,
    pub scene: Vector3<f64>,
    pub weight: f64,
}

/// The rotation `R` maximising `sum w (scene . R model)` (Horn's closed form of the quaternion
/// method); `None` when the directions do not fix a rotation (all parallel).
pub fn rotation_from_directions(pairs: &[DirectionPair]) -> Option<UnitQuaternion<f64>> {
    let m: Matrix3<f64> = pairs.iter().map(|p| p.weight * p.model * p.scene.transpose()).sum();
    let (sxx, sxy, sxz) = (m[(0, 0)], m[(0, 1)], m[(0, 2)]);
    let (syx, syy, syz) = (m[(1, 0)], m[(1, 1)], m[(1, 2)]);
    let (szx, szy, szz) = (m[(2, 0)], m[(2, 1)], m[(2, 2)]);
    #[rustfmt::skip]
    let n = Matrix4::new(
        sxx + syy + szz, syz - szy,        szx - sxz,        sxy - syx,
        syz - szy,       sxx - syy - szz,  sxy + syx,        szx + sxz,
        szx - sxz,       sxy + syx,       -sxx + syy - szz,  syz + szy,
        sxy - syx,       szx + sxz,        syz + szy,       -sxx - syy + szz,
    );
    let eig = n.symmetric_eigen();
    let mut order: Vec<usize> = (0..4).collect();
    order.sort_by(|&a, &b| eig.eigenvalues[b].total_cmp(&eig.eigenvalues[a]));
    // Parallel directions leave the top eigenvalue repeated: the rotation about them is free.
    if (eig.eigenvalues[order[0]] - eig.eigenvalues[order[1]]).abs() < 1e-9 * eig.eigenvalues[order[0]].abs().max(1.0) {
        return None;
    }
    let q = eig.eigenvectors.column(order[0]);
    Some(UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3])))
}

/// [`rotation_from_directions`] for two equally weighted pairs, in closed form: the optimum
/// turns the model pair's bisector frame (the unit sum and difference of the two directions,
/// and their cross product) onto the scene pair's, whatever the two angles between the
/// directions. The matcher seeds thousands of hypotheses from two lines each, and an
/// eigen-decomposition per seed was a fifth of its time. `None` when either pair is parallel.
pub fn rotation_from_two_directions(model: [Vector3<f64>; 2], scene: [Vector3<f64>; 2]) -> Option<UnitQuaternion<f64>> {
    let frame = |[u, v]: [Vector3<f64>; 2]| {
        let (sum, diff) = ((u + v).try_normalize(1e-9)?, (u - v).try_normalize(1e-9)?);
        Some(Matrix3::from_columns(&[sum, diff, sum.cross(&diff)]))
    };
    let (m, s) = (frame(model)?, frame(scene)?);
    let r = nalgebra::Rotation3::from_matrix_unchecked(s * m.transpose());
    Some(UnitQuaternion::from_rotation_matrix(&r))
}

/// A scene point that should lie on a model line (given by a point and unit direction, in the
/// model frame), weighted.
#[derive(Debug, Clone, Copy)]
pub struct PointOnLine {
    pub scene: Point3<f64>,
    pub model_point: Point3<f64>,
    pub model_direction: Vector3<f64>,
    pub weight: f64,
}

/// The translation `t` minimising `sum w |P (scene - (R model_point + t))|^2`, `P` projecting
/// across the rotated model line; `None` when the lines do not fix it (all parallel).
pub fn translation_from_points(rotation: &UnitQuaternion<f64>, points: &[PointOnLine]) -> Option<Vector3<f64>> {
    // As a matrix: it turns a vector in half the operations a quaternion does.
    let rotation = rotation.to_rotation_matrix();
    let mut a = Matrix3::zeros();
    let mut b = Vector3::zeros();
    for p in points {
        let d = rotation * p.model_direction;
        let across = Matrix3::identity() - d * d.transpose();
        a += p.weight * across;
        b += p.weight * across * (p.scene.coords - rotation * p.model_point.coords);
    }
    // Near-parallel lines leave `a` close to singular (its determinant is the product of its
    // eigenvalues, its trace their sum).
    if a.determinant() < 1e-9 * a.trace().powi(3).max(1e-36) {
        return None;
    }
    a.try_inverse().map(|inv| inv * b)
}

/// Both steps: the pose mapping model coordinates to scene coordinates.
pub fn pose_from_lines(directions: &[DirectionPair], points: &[PointOnLine]) -> Option<Isometry3<f64>> {
    let r = rotation_from_directions(directions)?;
    let t = translation_from_points(&r, points)?;
    Some(Isometry3::from_parts(Translation3::from(t), r))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn truth() -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::new(0.05, -0.02, 0.9), UnitQuaternion::from_euler_angles(0.4, -1.1, 2.3))
    }

    #[test]
    fn two_skew_lines_fix_the_pose_exactly() {
        let pose = truth();
        let lines = [
            (Point3::new(0.0, 0.0, 0.0), Vector3::new(1.0, 0.0, 0.0)),
            (Point3::new(0.01, 0.03, 0.02), Vector3::new(0.0, 0.6, 0.8)),
        ];
        let directions: Vec<DirectionPair> =
            lines.iter().map(|(_, d)| DirectionPair { model: *d, scene: pose.rotation * d, weight: 1.0 }).collect();
        // Scene points anywhere along the lines: the translation must not care where.
        let points: Vec<PointOnLine> = lines
            .iter()
            .flat_map(|(p, d)| {
                [0.013, 0.071].map(|s| PointOnLine {
                    scene: pose * (p + d * s),
                    model_point: *p,
                    model_direction: *d,
                    weight: 1.0,
                })
            })
            .collect();
        let got = pose_from_lines(&directions, &points).unwrap();
        assert!((got.to_homogeneous() - pose.to_homogeneous()).norm() < 1e-9, "{got} vs {pose}");
    }

    #[test]
    fn the_two_direction_closed_form_is_the_least_squares_rotation() {
        let pose = truth();
        let cases = [
            ([Vector3::x(), Vector3::new(0.0, 0.6, 0.8)], Vector3::new(0.01, -0.02, 0.005)),
            ([Vector3::new(0.3, 0.1, 0.95).normalize(), Vector3::new(-0.7, 0.7, 0.1).normalize()], Vector3::zeros()),
            ([Vector3::y(), Vector3::new(-0.9, -0.4, 0.0).normalize()], Vector3::new(-0.03, 0.0, 0.02)),
        ];
        for (k, (dirs, noise)) in cases.iter().enumerate() {
            let scene = [(pose.rotation * dirs[0] + noise).normalize(), pose.rotation * dirs[1]];
            let pairs: Vec<DirectionPair> =
                (0..2).map(|i| DirectionPair { model: dirs[i], scene: scene[i], weight: 1.0 }).collect();
            let by_eigen = rotation_from_directions(&pairs).unwrap();
            let closed = rotation_from_two_directions(*dirs, scene).unwrap();
            assert!(closed.angle_to(&by_eigen) < 1e-9, "case {k}: {} rad apart", closed.angle_to(&by_eigen));
        }
        assert!(rotation_from_two_directions([Vector3::x(), Vector3::x()], [Vector3::y(), Vector3::z()]).is_none());
    }

    #[test]
    fn parallel_lines_alone_do_not_fix_a_rotation() {
        let d = Vector3::new(0.0, 0.0, 1.0);
        let pairs =
            [DirectionPair { model: d, scene: d, weight: 1.0 }, DirectionPair { model: d, scene: d, weight: 2.0 }];
        assert!(rotation_from_directions(&pairs).is_none());
    }

    #[test]
    fn noisy_directions_give_the_least_squares_rotation() {
        let pose = truth();
        let dirs = [Vector3::x(), Vector3::y(), Vector3::z(), Vector3::new(1.0, 1.0, 0.0).normalize()];
        let noise = [
            Vector3::new(0.002, -0.001, 0.0),
            Vector3::new(0.0, 0.001, -0.002),
            Vector3::new(-0.001, 0.0, 0.001),
            Vector3::zeros(),
        ];
        let pairs: Vec<DirectionPair> = dirs
            .iter()
            .zip(noise)
            .map(|(d, n)| DirectionPair { model: *d, scene: (pose.rotation * d + n).normalize(), weight: 1.0 })
            .collect();
        let r = rotation_from_directions(&pairs).unwrap();
        assert!(r.angle_to(&pose.rotation) < 0.003, "{} rad off", r.angle_to(&pose.rotation));
    }
}
