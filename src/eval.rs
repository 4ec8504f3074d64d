//! Evaluation of the vision front end against ground truth (the only code that reads it).

use crate::front_end::FrontEnd;
use crate::truth::TruthScene;
use mesh::StereoCalibration;
use serde::Serialize;
use vision::rectify::Rectification;

/// How matched disparities compare with the truth.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct DisparityStats {
    /// Matches with a ground-truth disparity (a surface behind the left edgel).
    pub evaluated: usize,
    /// Of those, within 0.5 px of the true disparity.
    pub within_0_5px: usize,
    /// Of those, more than 2 px off.
    pub wrong: usize,
}

impl DisparityStats {
    pub fn add(&mut self, other: &DisparityStats) {
        self.evaluated += other.evaluated;
        self.within_0_5px += other.within_0_5px;
        self.wrong += other.wrong;
    }

    pub fn within_fraction(&self) -> f64 {
        self.within_0_5px as f64 / self.evaluated.max(1) as f64
    }

    pub fn wrong_fraction(&self) -> f64 {
        self.wrong as f64 / self.evaluated.max(1) as f64
    }
}

/// Compares every match's disparity with the true one at its left edgel (the nearer surface's
/// at an occluding boundary).
pub fn disparity_stats(
    fe: &FrontEnd,
    truth: &TruthScene,
    calib: &StereoCalibration,
) -> DisparityStats {
    let rect = Rectification::new(calib);
    let mut stats = DisparityStats::default();
    for m in &fe.matches {
        let e = &fe.left.edgels[m.left as usize];
        let Some(d) = truth.disparity(
            &calib.left,
            &rect,
            e.x as f64,
            e.y as f64,
            e.orientation as f64,
        ) else {
            continue;
        };
        let err = (m.disparity as f64 - d).abs();
        stats.evaluated += 1;
        stats.within_0_5px += usize::from(err <= 0.5);
        stats.wrong += usize::from(err > 2.0);
    }
    stats
}
