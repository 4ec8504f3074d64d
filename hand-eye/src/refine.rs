//! Nonlinear least squares on the flag's points: with `X = cam_from_base` and
//! `Y = gripper_from_flag`, each point `p` of the flag in each sighting gives the residual
//! `C_i p - X B_i Y p` (metres, in the camera frame). Minimised by Levenberg-Marquardt (the
//! `levenberg-marquardt` crate) over 12 parameters: small rotation vectors and translations
//! added to `X` and `Y`. The Jacobian is taken by central differences (12 columns of a cheap
//! residual), which no crate does better for a problem this small.
//!
//! The covariance of the result accounts for how vision errs: a sighting's error is one pose
//! error of the flag, shared by all its points, so the points are not independent and the
//! textbook `s^2 (J^T J)^-1` would understate it several times (see
//! [`PointProblem::covariance`]).

use crate::pose::exp;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Point3, SMatrix, Translation3, Vector3};
use nalgebra_lm::{Dyn, Owned};

/// Parameters: rotation vector and translation added to `X`, then to `Y`.
pub const PARAMS: usize = 12;

/// The problem: sightings, the flag's points, and the start the parameters are offsets from.
#[derive(Debug, Clone)]
pub struct PointProblem<'a> {
    pub sightings: &'a [(Isometry3<f64>, Isometry3<f64>)],
    pub points: &'a [Point3<f64>],
    pub start: (Isometry3<f64>, Isometry3<f64>),
    params: [f64; PARAMS],
}

impl<'a> PointProblem<'a> {
    pub fn new(
        sightings: &'a [(Isometry3<f64>, Isometry3<f64>)],
        points: &'a [Point3<f64>],
        start: (Isometry3<f64>, Isometry3<f64>),
    ) -> PointProblem<'a> {
        PointProblem { sightings, points, start, params: [0.0; PARAMS] }
    }

    /// `(cam_from_base, gripper_from_flag)` at parameters `p`.
    pub fn transforms_at(&self, p: &[f64; PARAMS]) -> (Isometry3<f64>, Isometry3<f64>) {
        let apply = |iso: &Isometry3<f64>, q: &[f64]| {
            Isometry3::from_parts(
                Translation3::from(iso.translation.vector + Vector3::new(q[3], q[4], q[5])),
                exp(&Vector3::new(q[0], q[1], q[2])) * iso.rotation,
            )
        };
        (apply(&self.start.0, &p[..6]), apply(&self.start.1, &p[6..]))
    }

    pub fn transforms(&self) -> (Isometry3<f64>, Isometry3<f64>) {
        self.transforms_at(&self.params)
    }

    /// Every residual, sighting by sighting, point by point, x y z.
    pub fn residuals_at(&self, p: &[f64; PARAMS]) -> DVector<f64> {
        let (x, y) = self.transforms_at(p);
        let mut r = DVector::zeros(3 * self.points.len() * self.sightings.len());
        for (i, (b, c)) in self.sightings.iter().enumerate() {
            let predicted = x * b * y;
            for (k, pt) in self.points.iter().enumerate() {
                let d = c * pt - predicted * pt;
                r.rows_mut(3 * (i * self.points.len() + k), 3).copy_from(&d);
            }
        }
        r
    }

    /// The Jacobian by central differences.
    pub fn jacobian_at(&self, p: &[f64; PARAMS]) -> DMatrix<f64> {
        const H: f64 = 1e-7;
        let m = 3 * self.points.len() * self.sightings.len();
        let mut j = DMatrix::zeros(m, PARAMS);
        for k in 0..PARAMS {
            let (mut up, mut down) = (*p, *p);
            up[k] += H;
            down[k] -= H;
            j.set_column(k, &((self.residuals_at(&up) - self.residuals_at(&down)) / (2.0 * H)));
        }
        j
    }

    /// The covariance of the 12 parameters at the current solution. A sighting's error is one
    /// pose error of the flag shared by all its points, so each sighting's residuals are split
    /// into what a rigid motion of the flag explains (6 numbers a sighting, whose covariance
    /// is pooled over the sightings) and the rest (independent per point); the parameters'
    /// covariance follows from both through the Jacobian (`(J^T J)^-1 J^T W J (J^T J)^-1`).
    pub fn covariance(&self) -> Option<SMatrix<f64, PARAMS, PARAMS>> {
        let (j, r) = (self.jacobian_at(&self.params), self.residuals_at(&self.params));
        let bread: SMatrix<f64, PARAMS, PARAMS> = (j.transpose() * &j).fixed_view::<PARAMS, PARAMS>(0, 0).into_owned();
        let bread = bread.try_inverse()?;
        let rows = 3 * self.points.len();
        let g = self.sightings.len();
        let motions: Vec<DMatrix<f64>> = self.sightings.iter().map(|(_, c)| self.rigid_motion_basis(c)).collect();
        let mut pose_cov = SMatrix::<f64, 6, 6>::zeros();
        let mut rest = 0.0;
        let jtj_inv = DMatrix::from_column_slice(PARAMS, PARAMS, bread.as_slice());
        for (i, gi) in motions.iter().enumerate() {
            // The fit pulls each sighting's residuals towards zero by its leverage; undone
            // (as a jackknife would: `(I - H_ii)^-1 r_i`) before they measure the noise.
            let ji = j.rows(i * rows, rows);
            let leverage = ji * &jtj_inv * ji.transpose();
            let unpulled = (DMatrix::identity(rows, rows) - leverage).try_inverse()?;
            let ri = unpulled * r.rows(i * rows, rows);
            let e = (gi.transpose() * gi).try_inverse()? * gi.transpose() * &ri;
            let e6 = SMatrix::<f64, 6, 1>::from_column_slice(e.as_slice());
            pose_cov += e6 * e6.transpose();
            rest += (ri - gi * e).norm_squared();
        }
        let gf = g as f64;
        let pose_cov = pose_cov / gf;
        let rest_var = rest / (gf * (rows as f64 - 6.0)).max(1.0);
        let mut meat = SMatrix::<f64, PARAMS, PARAMS>::zeros();
        for (i, gi) in motions.iter().enumerate() {
            let ji = j.rows(i * rows, rows);
            let sdense = DMatrix::from_column_slice(6, 6, pose_cov.as_slice());
            let w = gi * sdense * gi.transpose() + DMatrix::identity(rows, rows) * rest_var;
            let m = ji.transpose() * w * ji;
            meat += m.fixed_view::<PARAMS, PARAMS>(0, 0).into_owned();
        }
        Some(bread * meat * bread)
    }

    /// How a sighting's measured flag points move under a small rigid motion of the flag:
    /// rotation vector about the flag's centre (camera axes), then translation: `3K x 6`. (About
    /// the flag's centre, not the camera's origin, so that one pooled covariance fits every
    /// sighting: turned about a far origin, the errors' translation part would depend on where
    /// each flag stood.)
    fn rigid_motion_basis(&self, cam_from_flag: &Isometry3<f64>) -> DMatrix<f64> {
        let mut g = DMatrix::zeros(3 * self.points.len(), 6);
        for (k, p) in self.points.iter().enumerate() {
            let q = cam_from_flag.rotation * p.coords;
            let cross = Matrix3::new(0.0, q.z, -q.y, -q.z, 0.0, q.x, q.y, -q.x, 0.0);
            g.view_mut((3 * k, 0), (3, 3)).copy_from(&cross);
            g.view_mut((3 * k, 3), (3, 3)).copy_from(&Matrix3::identity());
        }
        g
    }
}

fn to_lm(v: &DVector<f64>) -> nalgebra_lm::DVector<f64> {
    nalgebra_lm::DVector::from_column_slice(v.as_slice())
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for PointProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &nalgebra_lm::DVector<f64>) {
        self.params.copy_from_slice(x.as_slice());
    }

    fn params(&self) -> nalgebra_lm::DVector<f64> {
        nalgebra_lm::DVector::from_column_slice(&self.params)
    }

    fn residuals(&self) -> Option<nalgebra_lm::DVector<f64>> {
        Some(to_lm(&self.residuals_at(&self.params)))
    }

    fn jacobian(&self) -> Option<nalgebra_lm::DMatrix<f64>> {
        let j = self.jacobian_at(&self.params);
        Some(nalgebra_lm::DMatrix::from_column_slice(j.nrows(), j.ncols(), j.as_slice()))
    }
}

/// Minimises the problem from its start; the solved problem (its [`PointProblem::transforms`]
/// and [`PointProblem::covariance`]) and whether the solver reports success.
pub fn minimise(problem: PointProblem<'_>) -> (PointProblem<'_>, bool) {
    let (solved, report) = LevenbergMarquardt::new().with_tol(1e-15).minimize(problem);
    (solved, report.termination.was_successful())
}

/// The standard deviations of a covariance's blocks: for `X` (cam_from_base) and `Y`
/// (gripper_from_flag), rotation (radians, the largest axis) and translation (metres, the
/// largest axis).
pub fn sigmas(cov: &SMatrix<f64, PARAMS, PARAMS>) -> [f64; 4] {
    let largest = |k: usize| {
        let block: Matrix3<f64> = cov.fixed_view::<3, 3>(k, k).into_owned();
        block.symmetric_eigenvalues().max().max(0.0).sqrt()
    };
    [largest(0), largest(3), largest(6), largest(9)]
}
