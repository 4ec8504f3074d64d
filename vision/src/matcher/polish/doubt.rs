//! Doubt: reports that a turn of the same part fits as well as they do, in both images and on
//! the 3D lines, so that the cameras cannot tell which way round the part lies.
//!
//! The turn in stereo ([`super::turn_in_stereo`]) replaces a report only with a turn shown
//! sharper; where the two tie it keeps the report, right or not. Locating, that is all one can
//! do. A run can do better: a reading in doubt waits, while the parts around it are picked,
//! and is seen again with less in front of it and beside it (see `marvin`'s
//! `engine::run::pick_order`).

use super::{others_than, polished, shares_in_view, stereo_views};
use crate::matcher::model::{Located, MatchParams, MatcherModel, Seg};
use crate::matcher::support::support_at;
use crate::matcher::verify::ImageEvidence;
use nalgebra::{Isometry3, Point3};

/// A turn of a report ([`crate::matcher::turns::in_stereo`]), refitted on the 3D lines and
/// the left image and polished on both, and how it fares against the report.
#[derive(Debug, Clone)]
pub struct TurnedAlike {
    pub cam_from_model: Isometry3<f64>,
    /// The report's share of its wireframe in view that runs along edgels, in the left and the
    /// right image (what the other reports hide left out).
    pub report_shown: [f64; 2],
    /// The turn's.
    pub turn_shown: [f64; 2],
    /// The turn's 3D support as a share of the report's.
    pub support_kept: f64,
}

impl TurnedAlike {
    /// Whether the turn fits about as well as the report: it keeps [`TIE_KEEP_SUPPORT`] of
    /// the report's 3D support, and shows no less of its wireframe along edgels in view than the
    /// report less [`TIE_SLACK`], in each image and in the two together, or more than the
    /// report by [`SHOWN_MORE`] in either image (the two images disagree, or the turn is the
    /// sharper in one).
    pub fn fits_as_well(&self) -> bool {
        let sum = |s: &[f64; 2]| s[0] + s[1];
        let pairs = || self.turn_shown.iter().zip(&self.report_shown);
        let ties =
            sum(&self.turn_shown) >= sum(&self.report_shown) - TIE_SLACK && pairs().all(|(t, r)| *t >= r - TIE_SLACK);
        self.support_kept >= TIE_KEEP_SUPPORT && (ties || pairs().any(|(t, r)| *t >= r + SHOWN_MORE))
    }
}

/// See [`TurnedAlike::fits_as_well`]. Chosen on realistic tuning seeds, tuning seed 1's
/// calibrations (`marvin eval locate ... --doubt`; `dense.toml` 5001-5200 and `widgets.toml`
/// 4401-4600, 4009 reports, 25 false): these put 34 right reports and 12 false ones in doubt.
/// With a support of 0.7, 47 and 12; of 0.9, 25 and 8. Ties alone (no [`SHOWN_MORE`]) at 0.7,
/// 44 and 11; a slack of 0.05 instead of 0.1, 27 and 9.
const TIE_KEEP_SUPPORT: f64 = 0.8;
/// See [`TIE_KEEP_SUPPORT`].
const TIE_SLACK: f64 = 0.1;
/// See [`TIE_KEEP_SUPPORT`]: 0.02-0.05 put the same reports in doubt on the tuning seeds; on
/// the run's tuning seed 1167 (realistic `widgets.toml`), a widget standing on its long edge
/// was picked read end for end with its turn shown more in the left image by 0.045.
const SHOWN_MORE: f64 = 0.03;
/// A turn that lies within this (metres) of the report at every corner is the report again.
const APART_M: f64 = 0.005;

/// For each report that `asked` marks, the turn that shows most of its wireframe along edgels
/// in the two images together, of those that lie apart from it ([`APART_M`]) and fit as well
/// ([`TurnedAlike::fits_as_well`]): the report is in doubt. `None` where none does, where not
/// asked, and without the right image.
pub fn turned_alike(
    models: &[MatcherModel],
    (scene, p): (&[Seg], &MatchParams),
    ev: &ImageEvidence,
    located: &[Located],
    asked: &[bool],
) -> Vec<Option<TurnedAlike>> {
    use rayon::prelude::*;
    let Some((views, solids)) = stereo_views(models, ev, located) else { return vec![None; located.len()] };
    let turns = crate::matcher::shading::TurnedCandidates::default();
    let best_turn = |i: usize, r: &Located| {
        let model = models.iter().find(|m| m.name == r.model)?;
        let others = others_than(&solids, i);
        let in_view = |pose: &Isometry3<f64>| -> [f64; 2] {
            let shown = shares_in_view(model, pose, &views, &others);
            [shown[0], shown[1]]
        };
        let support = |pose: &Isometry3<f64>| support_at(model, pose, scene, p).0;
        let (report_shown, report_support) = (in_view(&r.cam_from_model), support(&r.cam_from_model));
        crate::matcher::turns::in_stereo(model)
            .iter()
            .filter(|turn| !crate::matcher::turns::is_symmetry(model, turn))
            .filter_map(|turn| turns.refit(model, (scene, p), ev, r.cam_from_model * turn))
            .map(|c| polished(model, &c.pose, &others, &views, None))
            .filter(|pose| lies_apart(model, &r.cam_from_model, pose))
            .map(|pose| TurnedAlike {
                report_shown,
                turn_shown: in_view(&pose),
                support_kept: support(&pose) / report_support.max(f64::EPSILON),
                cam_from_model: pose,
            })
            .filter(TurnedAlike::fits_as_well)
            .max_by(|a, b| a.turn_shown.iter().sum::<f64>().total_cmp(&b.turn_shown.iter().sum::<f64>()))
    };
    located
        .par_iter()
        .enumerate()
        .map(|(i, r)| asked.get(i).copied().unwrap_or(false).then(|| best_turn(i, r))?)
        .collect()
}

/// Whether some corner of `model` at `b` lies [`APART_M`] or more from every corner at `a`.
fn lies_apart(model: &MatcherModel, a: &Isometry3<f64>, b: &Isometry3<f64>) -> bool {
    let corners = |pose: &Isometry3<f64>| -> Vec<Point3<f64>> {
        model.lines.iter().flat_map(|l| [pose * l.a, pose * l.b]).collect()
    };
    let (at_a, at_b) = (corners(a), corners(b));
    at_b.iter().any(|x| at_a.iter().all(|y| (x - y).norm() >= APART_M))
}
