//! A closed-form start. Between sightings `i` and `j` the camera sees the flag move by
//! `A = C_j C_i^-1` while the robot moved its gripper by `B = B_j B_i^-1`, and
//! `A X = X B` for `X = cam_from_base`. The rotation of `X` takes each motion's rotation axis
//! on the robot side onto the camera side's (Park & Martin: least squares over the rotation
//! vectors, by SVD); its translation then solves `(R_A - I) t_X = R_X t_B - t_A` by linear
//! least squares. The flag in the gripper follows from each sighting, averaged.

use crate::motion::MIN_TURN_RAD;
use crate::pose::log;
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};

/// `cam_from_base` and `gripper_from_flag` from sightings `(base_from_gripper, cam_from_flag)`,
/// or `None` if the motions do not fix them (see [`crate::motion::check`]).
pub fn solve(sightings: &[(Isometry3<f64>, Isometry3<f64>)]) -> Option<(Isometry3<f64>, Isometry3<f64>)> {
    let pairs: Vec<(Isometry3<f64>, Isometry3<f64>)> = sightings
        .iter()
        .enumerate()
        .flat_map(|(i, (bi, ci))| sightings[i + 1..].iter().map(move |(bj, cj)| (cj * ci.inverse(), bj * bi.inverse())))
        .collect();
    let rotation = rotation(&pairs)?;
    let translation = translation(&pairs, &rotation)?;
    let cam_from_base = Isometry3::from_parts(Translation3::from(translation), rotation);
    Some((cam_from_base, flag_in_gripper(sightings, &cam_from_base)))
}

/// The rotation taking the robot-side motions' rotation vectors onto the camera side's.
fn rotation(pairs: &[(Isometry3<f64>, Isometry3<f64>)]) -> Option<UnitQuaternion<f64>> {
    let mut h = Matrix3::zeros();
    for (a, b) in pairs {
        let (alpha, beta) = (log(&a.rotation), log(&b.rotation));
        if beta.norm() > MIN_TURN_RAD {
            h += beta * alpha.transpose();
        }
    }
    nearest_rotation(&h).map(|r| UnitQuaternion::from_rotation_matrix(&r))
}

/// The rotation `R` maximising `trace(R H)` for `H = sum b a^T` (Kabsch): `R b ~ a`.
fn nearest_rotation(h: &Matrix3<f64>) -> Option<Rotation3<f64>> {
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let r = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    Some(Rotation3::from_matrix_unchecked(r))
}

fn translation(pairs: &[(Isometry3<f64>, Isometry3<f64>)], r_x: &UnitQuaternion<f64>) -> Option<Vector3<f64>> {
    let mut m = DMatrix::zeros(3 * pairs.len(), 3);
    let mut rhs = DVector::zeros(3 * pairs.len());
    for (k, (a, b)) in pairs.iter().enumerate() {
        let lhs = a.rotation.to_rotation_matrix().into_inner() - Matrix3::identity();
        let r = r_x * b.translation.vector - a.translation.vector;
        m.view_mut((3 * k, 0), (3, 3)).copy_from(&lhs);
        rhs.rows_mut(3 * k, 3).copy_from(&r);
    }
    let t = m.svd(true, true).solve(&rhs, 1e-12).ok()?;
    Some(Vector3::new(t[0], t[1], t[2]))
}

/// `gripper_from_flag = B_i^-1 X^-1 C_i`, averaged over the sightings (rotations by their
/// chordal mean).
fn flag_in_gripper(sightings: &[(Isometry3<f64>, Isometry3<f64>)], cam_from_base: &Isometry3<f64>) -> Isometry3<f64> {
    let each: Vec<Isometry3<f64>> = sightings.iter().map(|(b, c)| b.inverse() * cam_from_base.inverse() * c).collect();
    let n = each.len().max(1) as f64;
    let t = each.iter().map(|y| y.translation.vector).sum::<Vector3<f64>>() / n;
    let sum: Matrix3<f64> = each.iter().map(|y| y.rotation.to_rotation_matrix().into_inner()).sum();
    // The rotation nearest the sum: R maximising trace(R^T S), i.e. Kabsch with H = S^T.
    let r = nearest_rotation(&sum.transpose())
        .map_or(UnitQuaternion::identity(), |r| UnitQuaternion::from_rotation_matrix(&r));
    Isometry3::from_parts(Translation3::from(t), r)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pose::pose_error;

    #[test]
    fn exact_motions_give_the_transforms() {
        let x =
            Isometry3::from_parts(Translation3::new(0.1, -0.3, 1.2), UnitQuaternion::from_euler_angles(2.0, 0.4, -1.1));
        let y =
            Isometry3::from_parts(Translation3::new(0.02, 0.0, 0.03), UnitQuaternion::from_euler_angles(1.5, 0.0, 1.5));
        let bs = [
            (0.3, 0.1, 0.4, 0.1, 0.2, 0.0),
            (0.2, -0.2, 0.5, 0.5, 0.0, 1.0),
            (0.4, 0.2, 0.3, -0.3, 0.4, -0.5),
            (0.35, 0.0, 0.45, 0.0, -0.5, 2.0),
        ];
        let sightings: Vec<_> = bs
            .iter()
            .map(|&(x0, y0, z0, r, p, w)| {
                let b =
                    Isometry3::from_parts(Translation3::new(x0, y0, z0), UnitQuaternion::from_euler_angles(r, p, w));
                (b, x * b * y)
            })
            .collect();
        let (gx, gy) = solve(&sightings).unwrap();
        let (dt, dr) = pose_error(&gx, &x);
        assert!(dt < 1e-9 && dr < 1e-9, "{dt} {dr}");
        let (dt, dr) = pose_error(&gy, &y);
        assert!(dt < 1e-9 && dr < 1e-9, "{dt} {dr}");
    }
}
