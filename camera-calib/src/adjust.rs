//! The joint least-squares adjustment: every corner seen in every view, by one or both
//! cameras, reprojected through the cameras' intrinsics (distortion included), the right
//! camera's pose in the left's and each view's board pose; minimised by Levenberg-Marquardt
//! (the `levenberg-marquardt` crate) with Huber weights recomputed between rounds (a robust
//! loss by iteratively reweighted least squares), and the parameters' covariance
//! `s² (JᵀWJ)⁻¹` at the solution.
//!
//! Parameters, in order: the left camera's intrinsics ([`INTRINSICS`]); with two cameras the
//! right's, then `right_from_left` (rotation vector, translation); then each view's
//! `left_from_board` (rotation vector, translation). A one-camera problem has only its
//! intrinsics and its views. The Jacobian is taken per observation by central differences:
//! each corner depends on at most 21 parameters, so the dense matrix costs little to fill.

use crate::camera::{INTRINSICS, Intrinsics};
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{DMatrix, DVector, Isometry3, Point2, Point3, Translation3, UnitQuaternion, Vector3};
use nalgebra_lm::{Dyn, Owned};

/// One corner seen: by which camera (0 left, 1 right), in which view, which corner of the
/// board, where (pixels).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Observation {
    pub camera: usize,
    pub view: usize,
    pub corner: usize,
    pub pixel: Point2<f64>,
}

/// A pose as 6 parameters: rotation vector, translation.
pub fn pose_params(pose: &Isometry3<f64>) -> [f64; 6] {
    let w = pose.rotation.scaled_axis();
    let t = pose.translation.vector;
    [w.x, w.y, w.z, t.x, t.y, t.z]
}

pub fn pose_from(p: &[f64]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p[3], p[4], p[5]),
        UnitQuaternion::from_scaled_axis(Vector3::new(p[0], p[1], p[2])),
    )
}

/// The unknowns and how they sit in the parameter vector.
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    pub cameras: Vec<Intrinsics>,
    /// `right_from_left` (two cameras only).
    pub rig: Option<Isometry3<f64>>,
    /// Each view's `left_from_board` (or the one camera's `cam_from_board`).
    pub views: Vec<Isometry3<f64>>,
}

impl State {
    fn rig_offset(&self) -> usize {
        INTRINSICS * self.cameras.len()
    }

    fn view_offset(&self) -> usize {
        self.rig_offset() + if self.rig.is_some() { 6 } else { 0 }
    }

    pub fn len(&self) -> usize {
        self.view_offset() + 6 * self.views.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn to_params(&self) -> Vec<f64> {
        let mut p: Vec<f64> = self.cameras.iter().flat_map(|c| c.to_params()).collect();
        p.extend(self.rig.iter().flat_map(pose_params));
        p.extend(self.views.iter().flat_map(pose_params));
        p
    }

    pub fn set_params(&mut self, p: &[f64]) {
        for (k, c) in self.cameras.iter_mut().enumerate() {
            *c = Intrinsics::from_params(&p[k * INTRINSICS..]);
        }
        if self.rig.is_some() {
            self.rig = Some(pose_from(&p[self.rig_offset()..]));
        }
        let v0 = self.view_offset();
        for (k, v) in self.views.iter_mut().enumerate() {
            *v = pose_from(&p[v0 + 6 * k..]);
        }
    }

    /// The parameters an observation depends on, as indices into the parameter vector.
    fn dependencies(&self, o: &Observation) -> Vec<usize> {
        let mut d: Vec<usize> = (o.camera * INTRINSICS..(o.camera + 1) * INTRINSICS).collect();
        if o.camera == 1 {
            d.extend(self.rig_offset()..self.rig_offset() + 6);
        }
        let v = self.view_offset() + 6 * o.view;
        d.extend(v..v + 6);
        d
    }
}

/// Where `o`'s corner is imaged with parameters `p` laid out as `state`'s.
fn predict(state: &State, p: &[f64], o: &Observation, point: &Point3<f64>) -> Option<Point2<f64>> {
    let cam = Intrinsics::from_params(&p[o.camera * INTRINSICS..]);
    let left_from_board = pose_from(&p[state.view_offset() + 6 * o.view..]);
    let cam_from_board =
        if o.camera == 1 { pose_from(&p[state.rig_offset()..]) * left_from_board } else { left_from_board };
    cam.project(&(cam_from_board * point))
}

/// The least-squares problem: observations, the board's points, per-observation weights, and
/// which parameters are held fixed (k3 when it is not solved for).
#[derive(Debug, Clone)]
pub struct Problem<'a> {
    pub observations: &'a [Observation],
    pub points: &'a [Point3<f64>],
    pub state: State,
    pub weights: Vec<f64>,
    /// Indices of the parameters that move.
    free: Vec<usize>,
    params: Vec<f64>,
}

/// A residual for a point that fell behind the camera: large, so the solver backs off.
const BEHIND: f64 = 1e6;

impl<'a> Problem<'a> {
    pub fn new(
        observations: &'a [Observation],
        points: &'a [Point3<f64>],
        state: State,
        solve_k3: bool,
    ) -> Problem<'a> {
        let params = state.to_params();
        let k3 = |i: usize| i < INTRINSICS * state.cameras.len() && i % INTRINSICS == 8;
        let free = (0..params.len()).filter(|&i| solve_k3 || !k3(i)).collect();
        Problem { observations, points, weights: vec![1.0; observations.len()], state, free, params }
    }

    /// Every observation's reprojection error (pixels, predicted minus seen).
    pub fn errors(&self) -> Vec<nalgebra::Vector2<f64>> {
        self.observations
            .iter()
            .map(|o| match predict(&self.state, &self.params, o, &self.points[o.corner]) {
                Some(q) => q - o.pixel,
                None => nalgebra::Vector2::new(BEHIND, BEHIND),
            })
            .collect()
    }

    fn residual_vector(&self) -> DVector<f64> {
        let e = self.errors();
        DVector::from_iterator(
            2 * e.len(),
            e.iter().zip(&self.weights).flat_map(|(e, w)| (e * w.sqrt()).into_iter().copied().collect::<Vec<_>>()),
        )
    }

    /// The weighted Jacobian over the free parameters.
    fn jacobian_matrix(&self) -> DMatrix<f64> {
        let column: Vec<Option<usize>> = {
            let mut c = vec![None; self.params.len()];
            for (k, &i) in self.free.iter().enumerate() {
                c[i] = Some(k);
            }
            c
        };
        let mut j = DMatrix::zeros(2 * self.observations.len(), self.free.len());
        let mut p = self.params.clone();
        for (row, o) in self.observations.iter().enumerate() {
            let point = &self.points[o.corner];
            let w = self.weights[row].sqrt();
            for i in self.state.dependencies(o) {
                let Some(col) = column[i] else { continue };
                let h = 1e-6 * p[i].abs().max(1e-2);
                let x = p[i];
                p[i] = x + h;
                let up = predict(&self.state, &p, o, point);
                p[i] = x - h;
                let down = predict(&self.state, &p, o, point);
                p[i] = x;
                if let (Some(a), Some(b)) = (up, down) {
                    let d = (a - b) * (w / (2.0 * h));
                    j[(2 * row, col)] = d.x;
                    j[(2 * row + 1, col)] = d.y;
                }
            }
        }
        j
    }

    /// The covariance of the free parameters at the current solution, `s² (JᵀWJ)⁻¹` with `s²`
    /// the weighted residuals' variance per degree of freedom; as a full-size matrix over all
    /// parameters (fixed ones zero).
    pub fn covariance(&self) -> Option<DMatrix<f64>> {
        let j = self.jacobian_matrix();
        let r = self.residual_vector();
        let dof = (r.len() as f64 - self.free.len() as f64).max(1.0);
        let s2 = r.norm_squared() / dof;
        let inv = (j.transpose() * &j).try_inverse()? * s2;
        let n = self.params.len();
        let mut full = DMatrix::zeros(n, n);
        for (a, &i) in self.free.iter().enumerate() {
            for (b, &k) in self.free.iter().enumerate() {
                full[(i, k)] = inv[(a, b)];
            }
        }
        Some(full)
    }

    /// Huber weights for the current errors: 1 within `c` pixels, `c / e` beyond, with `c`
    /// three robust standard deviations (from the median error) and at least `floor_px`.
    pub fn reweight(&mut self, floor_px: f64) {
        let e: Vec<f64> = self.errors().iter().map(|e| e.norm()).collect();
        let mut sorted = e.clone();
        sorted.sort_by(f64::total_cmp);
        // The median of a 2D Gaussian error's length is 1.1774 sigma.
        let sigma = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0) / 1.1774;
        let c = (3.0 * sigma).max(floor_px);
        self.weights = e.iter().map(|&e| if e <= c { 1.0 } else { c / e }).collect();
    }

    fn sync(&mut self) {
        let p = self.params.clone();
        self.state.set_params(&p);
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &nalgebra_lm::DVector<f64>) {
        for (k, &i) in self.free.iter().enumerate() {
            self.params[i] = x[k];
        }
        self.sync();
    }

    fn params(&self) -> nalgebra_lm::DVector<f64> {
        nalgebra_lm::DVector::from_iterator(self.free.len(), self.free.iter().map(|&i| self.params[i]))
    }

    fn residuals(&self) -> Option<nalgebra_lm::DVector<f64>> {
        Some(nalgebra_lm::DVector::from_column_slice(self.residual_vector().as_slice()))
    }

    fn jacobian(&self) -> Option<nalgebra_lm::DMatrix<f64>> {
        let j = self.jacobian_matrix();
        Some(nalgebra_lm::DMatrix::from_column_slice(j.nrows(), j.ncols(), j.as_slice()))
    }
}

/// Minimises `problem` with Huber weights: `rounds` solves, the weights recomputed from the
/// errors before each but the first. Returns the solved problem and whether the last solve
/// reported success.
pub fn minimise(mut problem: Problem<'_>, rounds: usize, floor_px: f64) -> (Problem<'_>, bool) {
    let mut ok = false;
    for round in 0..rounds.max(1) {
        if round > 0 {
            problem.reweight(floor_px);
        }
        let (solved, report) = LevenbergMarquardt::new().with_tol(1e-15).with_patience(200).minimize(problem);
        problem = solved;
        ok = report.termination.was_successful();
    }
    (problem, ok)
}
