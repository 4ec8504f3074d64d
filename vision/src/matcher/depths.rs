//! Stereo's depths at the left image's edgels, edgel by edgel: the evidence of PMF's matches kept
//! apart from the lines fitted to them, so that a reading can be checked edgel by edgel
//! against the depths of the edges it claims ([`super::verify::depth_agreement`]). A part
//! read turned over lies along many of the same image edges as the part itself, but puts some
//! of them at other depths.

use crate::front_end::FrontEnd;
use crate::front_end::canny::EdgeMap;
use crate::front_end::rectify::Rectification;

/// Per edgel of the left image's edge map: the depth (`cam` frame z, metres) stereo gave it,
/// and the depth one pixel of disparity spans there (NaN for an edgel left unmatched). Kept
/// per edgel, not per pixel: a few thousand entries, found through the edge map's pixels.
pub struct EdgelDepths {
    at: Vec<[f32; 2]>,
}

/// Edgels within this distance (pixels) of an image point are asked for its depth.
const NEAR_PX: i64 = 2;

impl EdgelDepths {
    /// No depths yet, for the edgels of `edges`.
    pub fn new(edges: &EdgeMap) -> EdgelDepths {
        EdgelDepths { at: vec![[f32::NAN; 2]; edges.edgels.len()] }
    }

    /// The depths of one front-end run's matches, for its left edge map.
    pub fn of(fe: &FrontEnd, rect: &Rectification) -> EdgelDepths {
        let mut depths = EdgelDepths::new(&fe.left);
        for m in fe.matches.iter().filter(|m| m.disparity > 0.0) {
            let z = rect.triangulate(m.x as f64, m.y as f64, m.disparity as f64).z;
            depths.insert(m.left as usize, z, z / m.disparity as f64);
        }
        depths
    }

    /// Records depth `z` (metres, one pixel of disparity spanning `per_px`) for edgel `i`.
    pub fn insert(&mut self, i: usize, z: f64, per_px: f64) {
        if let Some(at) = self.at.get_mut(i) {
            *at = [z as f32, per_px as f32];
        }
    }

    /// The depth stereo gave edgel `i` and the depth one pixel of disparity spans there
    /// (metres), if it was matched.
    pub fn of_edgel(&self, i: usize) -> Option<(f64, f64)> {
        let [z, per_px] = *self.at.get(i)?;
        (!z.is_nan()).then_some((z as f64, per_px as f64))
    }

    /// Whether an edgel of `edges` near image point `(x, y)` lies at depth `z`, within
    /// `tolerance_px` of disparity: `None` where no edgel near it has a depth. Any one agreeing
    /// is enough (near a corner the edgels of two edges at different depths lie side by side).
    pub fn agree(&self, edges: &EdgeMap, x: f64, y: f64, z: f64, tolerance_px: f64) -> Option<bool> {
        let (cx, cy) = (crate::image::nearest_px(x), crate::image::nearest_px(y));
        let mut found = None;
        for py in (cy - NEAR_PX).max(0)..=(cy + NEAR_PX).min(edges.height as i64 - 1) {
            for px in (cx - NEAR_PX).max(0)..=(cx + NEAR_PX).min(edges.width as i64 - 1) {
                let Some(i) = edges.edgel_at(px as usize, py as usize) else { continue };
                let [depth, per_px] = self.at[i as usize];
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
    use crate::front_end::canny::Edgel;

    #[test]
    fn an_edgel_near_a_point_says_whether_its_depth_is_the_models() {
        let mut edges = EdgeMap::new(64, 64);
        let edgel = |x: f32, y: f32| Edgel { x, y, orientation: 0.0, contrast: 50.0, sides: [0.0; 2] };
        edges.push(10 * 64 + 10, edgel(10.0, 10.0));
        edges.push(10 * 64 + 11, edgel(11.0, 10.0));
        edges.push(30 * 64 + 30, edgel(30.0, 30.0));
        let mut d = EdgelDepths::new(&edges);
        d.insert(0, 0.9, 0.004);
        assert_eq!(d.agree(&edges, 9.4, 8.6, 0.905, 1.5), Some(true), "5 mm off, 1.25 px of disparity");
        assert_eq!(d.agree(&edges, 9.4, 8.6, 0.92, 1.5), Some(false), "20 mm off");
        assert_eq!(d.agree(&edges, 7.0, 10.0, 0.9, 1.5), None, "three pixels away");
        assert_eq!(d.agree(&edges, 30.0, 30.0, 0.9, 1.5), None, "an edgel stereo left unmatched");
        // Beside it, an edgel of a nearer edge: either agreeing will do.
        d.insert(1, 0.85, 0.004);
        assert_eq!(d.agree(&edges, 10.0, 10.0, 0.85, 1.5), Some(true));
        assert_eq!(d.agree(&edges, 10.0, 10.0, 0.9, 1.5), Some(true));
    }
}
