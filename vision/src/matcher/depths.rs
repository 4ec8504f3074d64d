//! Stereo's depths at the left image's edgels, by pixel: the evidence of PMF's matches kept
//! apart from the lines fitted to them, so that a reading can be checked edgel by edgel
//! against the depths of the edges it claims ([`super::verify::depth_agreement`]). A part
//! read turned over lies along many of the same image edges as the part itself, but puts some
//! of them at other depths.

use crate::front_end::FrontEnd;
use crate::front_end::rectify::Rectification;

/// Per pixel of the left image: the depth (`cam` frame z, metres) of the matched edgel there,
/// and the depth one pixel of disparity spans at it (NaN where no edgel was matched).
pub struct EdgelDepths {
    width: usize,
    height: usize,
    at: Vec<[f32; 2]>,
}

/// Edgels within this distance (pixels) of an image point are asked for its depth.
const NEAR_PX: i64 = 2;

impl EdgelDepths {
    /// No depths yet, for an image `width` x `height`.
    pub fn new(width: usize, height: usize) -> EdgelDepths {
        EdgelDepths { width, height, at: vec![[f32::NAN; 2]; width * height] }
    }

    /// The depths of one front-end run's matches.
    pub fn of(fe: &FrontEnd, rect: &Rectification) -> EdgelDepths {
        let mut depths = EdgelDepths::new(fe.left.width, fe.left.height);
        for m in fe.matches.iter().filter(|m| m.disparity > 0.0) {
            let z = rect.triangulate(m.x as f64, m.y as f64, m.disparity as f64).z;
            let pixel = fe.left.pixel[m.left as usize] as usize;
            depths.at[pixel] = [z as f32, (z / m.disparity as f64) as f32];
        }
        depths
    }

    /// Records depth `z` (metres, one pixel of disparity spanning `per_px`) at pixel `(x, y)`.
    pub fn insert(&mut self, x: usize, y: usize, z: f64, per_px: f64) {
        if x < self.width && y < self.height {
            self.at[y * self.width + x] = [z as f32, per_px as f32];
        }
    }

    /// Whether an edgel near image point `(x, y)` lies at depth `z`, within `tolerance_px` of
    /// disparity: `None` where no edgel near it has a depth. Any one agreeing is enough (near
    /// a corner the edgels of two edges at different depths lie side by side).
    pub fn agree(&self, x: f64, y: f64, z: f64, tolerance_px: f64) -> Option<bool> {
        let (cx, cy) = (x.round() as i64, y.round() as i64);
        let mut found = None;
        for py in (cy - NEAR_PX).max(0)..=(cy + NEAR_PX).min(self.height as i64 - 1) {
            for px in (cx - NEAR_PX).max(0)..=(cx + NEAR_PX).min(self.width as i64 - 1) {
                let [depth, per_px] = self.at[py as usize * self.width + px as usize];
                if depth.is_nan() {
                    continue;
                }
                if (depth as f64 - z).abs() <= tolerance_px * per_px as f64 {
                    return Some(true);
                }
                found = Some(false);
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_edgel_near_a_point_says_whether_its_depth_is_the_models() {
        let mut d = EdgelDepths::new(64, 64);
        d.insert(10, 10, 0.9, 0.004);
        assert_eq!(d.agree(11.4, 9.0, 0.905, 1.5), Some(true), "5 mm off, 1.25 px of disparity");
        assert_eq!(d.agree(11.4, 9.0, 0.92, 1.5), Some(false), "20 mm off");
        assert_eq!(d.agree(13.0, 10.0, 0.9, 1.5), None, "three pixels away");
        // Beside it, an edgel of a nearer edge: either agreeing will do.
        d.insert(11, 10, 0.85, 0.004);
        assert_eq!(d.agree(10.0, 10.0, 0.85, 1.5), Some(true));
        assert_eq!(d.agree(10.0, 10.0, 0.9, 1.5), Some(true));
    }
}
