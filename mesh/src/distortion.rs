//! Lens distortion in the OpenCV/ROS `plumb_bob` model, on normalised image coordinates
//! (`x = X / Z`, `y = Y / Z` in the camera frame):
//!
//! ```text
//! r² = x² + y²,  radial = 1 + k1 r² + k2 r⁴ + k3 r⁶
//! x_d = x radial + 2 p1 x y + p2 (r² + 2 x²)
//! y_d = y radial + p1 (r² + 2 y²) + 2 p2 x y
//! ```
//!
//! then `u = fx x_d + cx`, `v = fy y_d + cy`. ROS's `camera_info` lists `D = [k1, k2, p1, p2, k3]`.

use serde::{Deserialize, Serialize};

/// The five `plumb_bob` coefficients, in ROS's order.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlumbBob {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    #[serde(default)]
    pub k3: f64,
}

impl PlumbBob {
    /// ROS's `D` vector: `[k1, k2, p1, p2, k3]`.
    pub fn from_d([k1, k2, p1, p2, k3]: [f64; 5]) -> Self {
        PlumbBob { k1, k2, p1, p2, k3 }
    }

    pub fn d(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    pub fn is_none(&self) -> bool {
        self.d().iter().all(|c| *c == 0.0)
    }

    /// Where an ideal (pinhole) normalised point lands through the lens.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
        let yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
        (xd, yd)
    }

    /// How the ideal point moves per move of the distorted one, at ideal point `(x, y)`: the
    /// inverse of [`Self::jacobian`] (`None` where the lens folds).
    pub fn inverse_jacobian(&self, x: f64, y: f64) -> Option<[[f64; 2]; 2]> {
        let [[a, b], [c, d]] = self.jacobian(x, y);
        let det = a * d - b * c;
        (det.abs() >= 1e-9).then(|| [[d / det, -b / det], [-c / det, a / det]])
    }

    /// The Jacobian of [`Self::distort`] at `(x, y)`: `[[dxd/dx, dxd/dy], [dyd/dx, dyd/dy]]`.
    fn jacobian(&self, x: f64, y: f64) -> [[f64; 2]; 2] {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        // d(radial)/d(r²)
        let dradial = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2);
        let (drdx, drdy) = (2.0 * x * dradial, 2.0 * y * dradial);
        [
            [
                radial + x * drdx + 2.0 * self.p1 * y + 6.0 * self.p2 * x,
                x * drdy + 2.0 * self.p1 * x + 2.0 * self.p2 * y,
            ],
            [
                y * drdx + 2.0 * self.p1 * x + 2.0 * self.p2 * y,
                radial + y * drdy + 6.0 * self.p1 * y + 2.0 * self.p2 * x,
            ],
        ]
    }

    /// The ideal normalised point that the lens puts at `(xd, yd)`: Newton's method from the
    /// distorted point, to 1e-12 (a millionth of a pixel at any focal length used here). `None`
    /// where it does not converge: beyond the fold of a strongly distorting lens.
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<(f64, f64)> {
        self.undistort_from((xd, yd), (xd, yd))
    }

    /// [`Self::undistort`] of `(xd, yd)` with Newton's method started at `start`, to the same
    /// tolerance. Started from a neighbouring point's answer, carried over by
    /// [`Self::inverse_jacobian`], it takes two steps where from the distorted point it takes
    /// four or five (a lens of k1 = -0.2 moves the image's corners 9 px).
    pub fn undistort_from(&self, (xd, yd): (f64, f64), start: (f64, f64)) -> Option<(f64, f64)> {
        let (mut x, mut y) = start;
        for _ in 0..30 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs().max(ey.abs()) < 1e-12 {
                return Some((x, y));
            }
            let [[a, b], [c, d]] = self.jacobian(x, y);
            let det = a * d - b * c;
            if det.abs() < 1e-9 {
                return None;
            }
            x -= (d * ex - b * ey) / det;
            y -= (a * ey - c * ex) / det;
        }
        let (fx, fy) = self.distort(x, y);
        ((fx - xd).abs().max((fy - yd).abs()) < 1e-9).then_some((x, y))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LENS: PlumbBob = PlumbBob { k1: -0.21, k2: 0.12, p1: 4e-4, p2: -3e-4, k3: -0.02 };

    #[test]
    fn undistort_inverts_distort_over_the_image() {
        for i in -10..=10 {
            for j in -10..=10 {
                let (x, y) = (i as f64 * 0.03, j as f64 * 0.03);
                let (xd, yd) = LENS.distort(x, y);
                let (ux, uy) = LENS.undistort(xd, yd).unwrap();
                assert!((ux - x).abs() < 1e-11 && (uy - y).abs() < 1e-11, "({x}, {y}) came back as ({ux}, {uy})");
            }
        }
    }

    #[test]
    fn undistorting_from_a_neighbours_answer_finds_the_same_point() {
        // Each point of a row started from the one before it, carried over by the inverse
        // Jacobian, as the rectification walks an image's edgels.
        let mut last: Option<((f64, f64), (f64, f64))> = None;
        for i in -30..=30 {
            let d = LENS.distort(i as f64 * 0.011, 0.25);
            let start = last.map_or(d, |(ld, lu)| {
                let j = LENS.inverse_jacobian(lu.0, lu.1).unwrap();
                let (dx, dy) = (d.0 - ld.0, d.1 - ld.1);
                (lu.0 + j[0][0] * dx + j[0][1] * dy, lu.1 + j[1][0] * dx + j[1][1] * dy)
            });
            let (from_start, alone) = (LENS.undistort_from(d, start).unwrap(), LENS.undistort(d.0, d.1).unwrap());
            assert!((from_start.0 - alone.0).abs() < 1e-11 && (from_start.1 - alone.1).abs() < 1e-11);
            last = Some((d, from_start));
        }
    }

    #[test]
    fn the_inverse_jacobian_undoes_the_jacobian() {
        let (x, y) = (-0.27, 0.19);
        let (j, inv) = (LENS.jacobian(x, y), LENS.inverse_jacobian(x, y).unwrap());
        let matrix = |m: [[f64; 2]; 2]| nalgebra::Matrix2::new(m[0][0], m[0][1], m[1][0], m[1][1]);
        assert!((matrix(j) * matrix(inv) - nalgebra::Matrix2::identity()).abs().max() < 1e-12);
    }

    #[test]
    fn the_jacobian_matches_finite_differences() {
        let (x, y, h) = (0.21, -0.17, 1e-6);
        let j = LENS.jacobian(x, y);
        let (px, py) = LENS.distort(x + h, y);
        let (mx, my) = LENS.distort(x - h, y);
        let (qx, qy) = LENS.distort(x, y + h);
        let (nx, ny) = LENS.distort(x, y - h);
        let fd = [[(px - mx) / (2.0 * h), (qx - nx) / (2.0 * h)], [(py - my) / (2.0 * h), (qy - ny) / (2.0 * h)]];
        for r in 0..2 {
            for c in 0..2 {
                assert!((j[r][c] - fd[r][c]).abs() < 1e-7, "J[{r}][{c}] {} vs {}", j[r][c], fd[r][c]);
            }
        }
    }

    #[test]
    fn barrel_distortion_pulls_corners_in() {
        let (xd, yd) = PlumbBob { k1: -0.2, ..Default::default() }.distort(0.25, 0.25);
        assert!(xd < 0.25 && yd < 0.25 && (xd - yd).abs() < 1e-15);
        assert_eq!(PlumbBob::default().distort(0.3, -0.1), (0.3, -0.1));
    }
}
