//! One camera as calibration models it: focal lengths and principal point (pixels, no skew)
//! and the lens's `plumb_bob` distortion ([`mesh::distortion::PlumbBob`]), projecting points
//! of its own frame (x right, y down, z along the optical axis; metres).

use mesh::distortion::PlumbBob;
use nalgebra::{Matrix3, Point2, Point3};
use serde::{Deserialize, Serialize};

/// A camera's intrinsic parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub distortion: PlumbBob,
}

/// The number of intrinsic parameters in [`Intrinsics::to_params`]'s order:
/// `fx fy cx cy k1 k2 p1 p2 k3`.
pub const INTRINSICS: usize = 9;

/// Names of the intrinsic parameters, in [`Intrinsics::to_params`]'s order.
pub const INTRINSIC_NAMES: [&str; INTRINSICS] = ["fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3"];

impl Intrinsics {
    /// A pinhole without distortion.
    pub fn pinhole(fx: f64, fy: f64, cx: f64, cy: f64) -> Intrinsics {
        Intrinsics { fx, fy, cx, cy, distortion: PlumbBob::default() }
    }

    pub fn to_params(&self) -> [f64; INTRINSICS] {
        let [k1, k2, p1, p2, k3] = self.distortion.d();
        [self.fx, self.fy, self.cx, self.cy, k1, k2, p1, p2, k3]
    }

    pub fn from_params(p: &[f64]) -> Intrinsics {
        Intrinsics {
            fx: p[0],
            fy: p[1],
            cx: p[2],
            cy: p[3],
            distortion: PlumbBob::from_d([p[4], p[5], p[6], p[7], p[8]]),
        }
    }

    /// The camera matrix `K`.
    pub fn k(&self) -> Matrix3<f64> {
        Matrix3::new(self.fx, 0.0, self.cx, 0.0, self.fy, self.cy, 0.0, 0.0, 1.0)
    }

    /// Where a point of the camera frame is imaged (pixels); `None` behind the camera.
    pub fn project(&self, p: &Point3<f64>) -> Option<Point2<f64>> {
        (p.z > 1e-9).then(|| {
            let (xd, yd) = self.distortion.distort(p.x / p.z, p.y / p.z);
            Point2::new(self.fx * xd + self.cx, self.fy * yd + self.cy)
        })
    }

    /// The ideal normalised coordinates `(X/Z, Y/Z)` of the ray imaged at pixel `(u, v)`.
    pub fn normalised(&self, u: f64, v: f64) -> Option<(f64, f64)> {
        self.distortion.undistort((u - self.cx) / self.fx, (v - self.cy) / self.fy)
    }

    /// How far (pixels) the lens moves pixel `(u, v)` from where a pinhole of the same `K`
    /// would image its ray.
    pub fn distortion_shift_px(&self, u: f64, v: f64) -> Option<f64> {
        let (x, y) = self.normalised(u, v)?;
        Some((self.fx * x + self.cx - u).hypot(self.fy * y + self.cy - v))
    }
}

/// The largest difference over an image of `size` (a 17 x 17 grid of pixels) between where
/// `got`'s distortion and `want`'s put each pixel's ray, both with `want`'s camera matrix: how
/// far apart the two lens models are, whatever their focal lengths and centres.
pub fn distortion_difference_px(got: &Intrinsics, want: &Intrinsics, size: [u32; 2]) -> f64 {
    let with_true_k = Intrinsics { distortion: got.distortion, ..*want };
    let mut worst: f64 = 0.0;
    for j in 0..=16 {
        for i in 0..=16 {
            let (u, v) = (i as f64 * (size[0] - 1) as f64 / 16.0, j as f64 * (size[1] - 1) as f64 / 16.0);
            let Some((x, y)) = want.normalised(u, v) else { continue };
            if let Some(p) = with_true_k.project(&Point3::new(x, y, 1.0)) {
                worst = worst.max((p.x - u).hypot(p.y - v));
            }
        }
    }
    worst
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ray_s_pixel_comes_back_as_the_ray() {
        let cam = Intrinsics {
            distortion: PlumbBob::from_d([-0.2, 0.09, 3e-4, -2e-4, 0.0]),
            ..Intrinsics::pinhole(1000.0, 1001.0, 250.0, 260.0)
        };
        let p = Point3::new(0.1, -0.07, 0.8);
        let uv = cam.project(&p).unwrap();
        let (x, y) = cam.normalised(uv.x, uv.y).unwrap();
        assert!((x - p.x / p.z).abs() < 1e-12 && (y - p.y / p.z).abs() < 1e-12);
        assert_eq!(Intrinsics::from_params(&cam.to_params()), cam);
    }
}
