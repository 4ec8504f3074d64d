//! The end-to-end run, MARVIN's whole cycle: the arm parks out of view, the stereo pair is
//! captured, the front end and the matcher locate the parts, the next one is chosen (lying
//! where it could, read on firm evidence, not under another, reachable, best supported) and its
//! grasp goes over the socket in the `cam` frame; the robot server picks it into the bin; again,
//! until nothing more is located. Nothing here reads the simulation's truth: poses come from vision, the
//! camera-to-robot transform from calibration. (Evaluation may watch through a hook, and judges afterwards.)

use crate::engine::client::Client;
use crate::engine::perception::{Pair, front_end, locate_parts_in_doubt, part_models};
use crate::protocol::{
    CaptureReply, Frame, PickOutcomeKind, PickReply, PickSpec, PlaceSpec, WireGrasp, WireObject, WirePose,
};
use anyhow::Context;
use nalgebra::Isometry3;
use std::time::Instant;
use vision::front_end::FrontEnd;
use vision::matcher::Located;

/// How a run goes.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// Cycles at most.
    pub max_cycles: usize,
    /// The bin picked objects go to (default: the server's first).
    pub bin: Option<String>,
    /// The cameras as calibrated (`marvin calibrate cameras`); without them, the calibration the
    /// captures carry.
    pub cameras: Option<mesh::StereoCalibration>,
}

impl Default for RunConfig {
    fn default() -> Self {
        RunConfig { max_cycles: 40, bin: None, cameras: None }
    }
}

/// One cycle.
#[derive(Debug, Clone)]
pub struct Cycle {
    /// Parts located in the capture.
    pub located: Vec<Located>,
    /// Of those, the ones read surely enough to go first ([`surely_read`]) that a turn of the
    /// part fits as well in both images: they wait too ([`pick_order`]).
    pub in_doubt: Vec<bool>,
    /// The one chosen and picked (index into `located`), if any.
    pub chosen: Option<usize>,
    /// The pick's reply, or the server's refusal.
    pub outcome: Option<Result<PickReply, String>>,
    /// Candidates whose pick could not be planned before one could.
    pub unplannable: usize,
    /// The pick was planned with the neighbours left out: every part was blocked by another.
    pub pushing_neighbours: bool,
    /// Stage times of this cycle's vision, ms: the front end's (processor time summed over the
    /// slices, and wall time of `slices` and `join`), `match`, `capture` (request and decode).
    pub timings_ms: Vec<(&'static str, f64)>,
    /// Wall time of the whole cycle, seconds.
    pub cycle_s: f64,
    /// The arm's joints (by URDF name) and the simulated time at the end of the cycle, as the
    /// server's `status` gives them.
    pub joints: std::collections::BTreeMap<String, f64>,
    pub gripper_opening_m: f64,
    pub sim_time_s: f64,
}

impl Cycle {
    /// A cycle with these stage times and nothing else yet.
    pub fn timed(timings_ms: Vec<(&'static str, f64)>) -> Cycle {
        Cycle {
            located: Vec::new(),
            in_doubt: Vec::new(),
            chosen: None,
            outcome: None,
            unplannable: 0,
            pushing_neighbours: false,
            timings_ms,
            cycle_s: 0.0,
            joints: Default::default(),
            gripper_opening_m: 0.0,
            sim_time_s: 0.0,
        }
    }

    /// The server's reply to the pick, when one was tried and not refused.
    pub fn reply(&self) -> Option<&PickReply> {
        self.outcome.as_ref().and_then(|o| o.as_ref().ok())
    }

    /// The model of the part chosen, when one was.
    pub fn chosen_model(&self) -> Option<&str> {
        Some(self.located.get(self.chosen?)?.model.as_str())
    }

    pub fn vision_ms(&self) -> f64 {
        self.timings_ms.iter().filter(|(n, _)| matches!(*n, "slices" | "join" | "match")).map(|(_, ms)| ms).sum()
    }
}

/// What a run reports as it goes (to print, and to record).
pub enum RunEvent<'a> {
    /// A capture and what the front end made of it.
    Captured { cycle: usize, capture: &'a CaptureReply, pair: &'a Pair, front_end: &'a FrontEnd },
    /// The parts located in it, and which are in doubt ([`Cycle::in_doubt`]).
    Located { cycle: usize, located: &'a [Located], in_doubt: &'a [bool] },
    /// A cycle done.
    Done(&'a Cycle),
}

/// Why a run stopped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stop {
    /// Nothing more was located.
    NothingLocated,
    /// Parts were located but none could be picked (planned, or not tried twice and failed).
    NothingPickable,
    MaxCycles,
}

/// A run's cycles and why it stopped.
#[derive(Debug, Clone)]
pub struct RunReport {
    pub cycles: Vec<Cycle>,
    pub stop: Stop,
}

/// A located part that failed this many picks is not tried again.
const MAX_TRIES: usize = 2;
/// Two sightings of a part are the same part within this distance, metres.
const SAME_PART_M: f64 = 0.01;

/// Runs pick cycles on a connected robot server that has `cam_from_base` (the calibration's).
/// `before_pick(client, cycle, chosen)` is called just before each pick (evaluation records the
/// truth there; the run path passes nothing); `observe` hears of each capture, what was located,
/// and each cycle.
pub fn run(
    client: &mut Client,
    library: &mesh::Library,
    config: &RunConfig,
    cam_from_base: &Isometry3<f64>,
    before_pick: &mut dyn FnMut(&mut Client, usize, &Located) -> anyhow::Result<()>,
    observe: &mut dyn FnMut(RunEvent<'_>) -> anyhow::Result<()>,
) -> anyhow::Result<RunReport> {
    let hello = client.hello(std::env::var("MARVIN_TOKEN").ok().as_deref())?;
    anyhow::ensure!(hello.calibrated, "the robot server has no hand-eye transform: calibrate first");
    let bin = config.bin.clone().or_else(|| hello.bins.first().cloned()).context("the cell has no bin")?;
    let bin_boxes = hello.bin_boxes.clone();
    let table_top = hello.table_top_base_m;
    // The table's top in `cam`, by the hand-eye calibration: `base` is level, z up.
    let cam_from_table = table_top.map(|top| cam_from_base * Isometry3::translation(0.0, 0.0, top));
    let models = part_models(library);
    let mut failed: Vec<(String, Isometry3<f64>)> = Vec::new();
    let mut cycles = Vec::new();
    for k in 0..config.max_cycles {
        let start = Instant::now();
        client.home().context("parking the arm out of view")?;
        let clock = Instant::now();
        let capture = client.capture()?;
        let pair = Pair::from_capture(&capture, config.cameras.as_ref())?;
        let capture_ms = clock.elapsed().as_secs_f64() * 1e3;
        let fe = front_end(&pair, cam_from_table.as_ref());
        let clock = Instant::now();
        let (located, in_doubt) = locate_parts_in_doubt(&models, &pair, &fe, cam_from_table.as_ref(), surely_read);
        let match_ms = clock.elapsed().as_secs_f64() * 1e3;
        observe(RunEvent::Captured { cycle: k, capture: &capture, pair: &pair, front_end: &fe })?;
        observe(RunEvent::Located { cycle: k, located: &located, in_doubt: &in_doubt })?;
        let mut timings_ms = fe.timings_ms.clone();
        timings_ms.extend([("match", match_ms), ("capture", capture_ms)]);
        let mut cycle = Cycle { located, in_doubt, sim_time_s: capture.sim_time_s, ..Cycle::timed(timings_ms) };
        if cycle.located.is_empty() {
            cycle.cycle_s = start.elapsed().as_secs_f64();
            observe(RunEvent::Done(&cycle))?;
            cycles.push(cycle);
            return Ok(RunReport { cycles, stop: Stop::NothingLocated });
        }
        let (resting, may_rest) = (
            resting(&cycle.located, library, cam_from_base, table_top, RESTING_M),
            resting(&cycle.located, library, cam_from_base, table_top, MAY_REST_M),
        );
        let order = pick_order((&cycle.located, &cycle.in_doubt), cam_from_base, &bin_boxes, &failed);
        // Parts that rest go first; those that only may rest wait until nothing else is left.
        let mut order: Vec<usize> = order.into_iter().filter(|&i| may_rest[i]).collect();
        order.sort_by_key(|&i| !resting[i]);
        // Each part with its neighbours avoided; where every one is blocked by another (parts
        // packed so that each one's fingers would touch the next), the first that plans with
        // the neighbours left out, its fingers pushing them aside as they close.
        let tries = order.iter().map(|&i| (i, true)).chain(order.iter().map(|&i| (i, false)));
        for (i, avoiding) in tries {
            if !avoiding && cycle.unplannable < order.len() {
                break;
            }
            let mut spec = pick_spec(&cycle.located, i, &bin);
            if !avoiding {
                spec.obstacles.clear();
            }
            match client.pick(PickSpec { plan_only: true, ..spec.clone() }) {
                Err(e) if e.wire().is_some() => {
                    cycle.unplannable += usize::from(avoiding);
                    continue;
                }
                Err(e) => return Err(e.into()),
                Ok(_) => {}
            }
            cycle.pushing_neighbours = !avoiding;
            before_pick(client, k, &cycle.located[i])?;
            cycle.chosen = Some(i);
            let reply = client.pick(spec).map_err(|e| e.to_string());
            if !matches!(&reply, Ok(r) if r.outcome == Some(PickOutcomeKind::Placed)) {
                failed.push((cycle.located[i].model.clone(), cycle.located[i].cam_from_model));
            }
            cycle.outcome = Some(reply);
            break;
        }
        let status = client.status()?;
        (cycle.joints, cycle.sim_time_s) = (status.joints, status.sim_time_s);
        cycle.gripper_opening_m = status.gripper_opening_mm * 1e-3;
        cycle.cycle_s = start.elapsed().as_secs_f64();
        observe(RunEvent::Done(&cycle))?;
        let picked = cycle.chosen.is_some();
        cycles.push(cycle);
        if !picked {
            return Ok(RunReport { cycles, stop: Stop::NothingPickable });
        }
    }
    Ok(RunReport { cycles, stop: Stop::MaxCycles })
}

/// The located parts in the order to try them: those already lying in a bin, and those that
/// failed [`MAX_TRIES`] picks, left out; parts read surely ([`surely_read`]) and not `in_doubt`
/// before the others; the highest first (nothing lies on top of it), and of parts at about the
/// same height the best supported.
///
/// Why the doubted wait: a part that a turn of itself fits as well in both images
/// (`vision::matcher::polish::doubt`) is read as often the wrong way round as the right,
/// and the matcher has nothing to choose by. Picked later, with its neighbours gone, it is seen
/// again with more of it in view. The wrong-model picks of `marvin eval run` on the tuning
/// seeds (realistic `widgets.toml` 961-1360, tuning seed 1's files) were three: a wedge and a
/// widget read turned about themselves, and a U-channel read on an L-bracket; the two turned
/// were both in doubt when picked, and waiting, neither was picked wrong (docs/TUNING.md,
/// "Readings in doubt wait in the run").
fn pick_order(
    (located, in_doubt): (&[Located], &[bool]),
    cam_from_base: &Isometry3<f64>,
    bins: &[crate::protocol::BinBox],
    failed: &[(String, Isometry3<f64>)],
) -> Vec<usize> {
    let base_from_cam = cam_from_base.inverse();
    let in_base = |l: &Located| base_from_cam * l.cam_from_model;
    // Anything over a bin's floor lies in it or on what is in it: parts pile up over the rim.
    let in_a_bin = |l: &Located| {
        let p = in_base(l).translation.vector;
        bins.iter().any(|b| {
            let over_floor = p.z >= b.centre_base_m[2] - b.size_m[2] / 2.0 - BIN_MARGIN_M;
            over_floor && (0..2).all(|k| (p[k] - b.centre_base_m[k]).abs() <= b.size_m[k] / 2.0 + BIN_MARGIN_M)
        })
    };
    let tries = |l: &Located| {
        failed
            .iter()
            .filter(|(m, pose)| {
                *m == l.model && (pose.translation.vector - l.cam_from_model.translation.vector).norm() < SAME_PART_M
            })
            .count()
    };
    let mut order: Vec<usize> =
        (0..located.len()).filter(|&i| !in_a_bin(&located[i]) && tries(&located[i]) < MAX_TRIES).collect();
    // Readings on weak evidence last; then heights in 1 cm bands, then support.
    let sure = |i: usize| surely_read(&located[i]) && !in_doubt.get(i).copied().unwrap_or(false);
    let band = |i: usize| (in_base(&located[i]).translation.z / 0.01).round() as i64;
    order.sort_by(|&a, &b| {
        sure(b).cmp(&sure(a)).then(band(b).cmp(&band(a))).then(located[b].support.total_cmp(&located[a].support))
    });
    order
}

/// A part read from fewer 3D lines than this (the second look's pose on one line and the
/// image) is tried only when no better grounded part is left: it is the least certain reading,
/// and what lies on or against it, gone, lets it be seen again. On seed 4014 (tuning) an
/// L-bracket leaning under a block, read from one 23 mm line 48 mm from where it lay, was the
/// highest part and went first, for nothing; after the block it was read right and placed.
const MIN_LINES_TO_GO_FIRST: usize = 2;

/// Whether a reading rests on evidence enough to go before the others: [`MIN_LINES_TO_GO_FIRST`]
/// 3D lines, [`MIN_SUPPORT_TO_GO_FIRST`] of its model's length along them and
/// [`MIN_IMAGE_TO_GO_FIRST`] of its wireframe along edgels. A reading short of any is tried
/// only when no surer one is left: the parts on and against it gone, it is read again, more of
/// it in view.
fn surely_read(l: &Located) -> bool {
    l.scene_lines.len() >= MIN_LINES_TO_GO_FIRST
        && l.support_fraction >= MIN_SUPPORT_TO_GO_FIRST
        && l.image_support >= MIN_IMAGE_TO_GO_FIRST
}

/// A reading matching less than this share of its model's length along 3D lines waits (see
/// [`MIN_IMAGE_TO_GO_FIRST`] for how it was chosen).
const MIN_SUPPORT_TO_GO_FIRST: f64 = 0.15;
/// A reading whose camera-facing wireframe runs along edgels for less than this share waits.
///
/// The wrong-model picks of `marvin eval run` (realistic `widgets.toml`, tuning seed 1's files)
/// are readings of this kind, and most come early, in clutter. Seeds 201-400: the two (an
/// L-bracket turned, one on a U-channel) had image support 0.52 and 0.59; making readings under
/// 0.65 wait, none was made, cleared 0.997 -> 0.994. Seeds 401-600: of the four, two had support
/// 0.10 (an L-bracket on a channel, a wedge on a hex prism), one image support 0.54; under 0.65
/// alone 3 were made, with [`MIN_SUPPORT_TO_GO_FIRST`] 0.15 as well 1 (a widget read as a block
/// and, once waiting, as a wedge), cleared 0.995 -> 0.994, picks placed 0.987 either way. Of the
/// readings `marvin eval locate` judged right on tuning seeds (realistic `widgets.toml` 1-300,
/// `dense.toml` 1-200), 9% and 18% wait by these three bars, and are picked later; of its
/// false reports, 0 of 2 and 13 of 20.
const MIN_IMAGE_TO_GO_FIRST: f64 = 0.65;

/// Whether each located part could lie where vision puts it: its lowest point on the table
/// (within `within`, metres), or over the table and on another part located (its lowest point no
/// higher than the other's highest, their footprints overlapping). A reading in mid-air or in
/// the table is a misreading, and a pick there would go for nothing. Without the table's height
/// every part may rest.
fn resting(
    located: &[Located],
    library: &mesh::Library,
    cam_from_base: &Isometry3<f64>,
    table_top: Option<f64>,
    within: f64,
) -> Vec<bool> {
    let Some(top) = table_top else { return vec![true; located.len()] };
    let base_from_cam = cam_from_base.inverse();
    let extent: Vec<Option<Extent>> =
        located.iter().map(|l| Some(Extent::of(library.get(&l.model)?, &(base_from_cam * l.cam_from_model)))).collect();
    (0..located.len())
        .map(|i| {
            let Some(e) = &extent[i] else { return true };
            if e.lowest < top - within {
                return false;
            }
            e.lowest <= top + within
                || extent.iter().enumerate().any(|(j, other)| {
                    other.as_ref().is_some_and(|o| {
                        j != i && o.highest >= e.lowest - within && (e.centre - o.centre).norm() < e.radius + o.radius
                    })
                })
        })
        .collect()
}

/// A part's lowest and highest points in the base frame, and the circle round its footprint.
struct Extent {
    lowest: f64,
    highest: f64,
    centre: nalgebra::Vector2<f64>,
    radius: f64,
}

impl Extent {
    fn of(model: &mesh::Model, base_from_model: &Isometry3<f64>) -> Extent {
        let points: Vec<nalgebra::Point3<f64>> = model.mesh.vertices.iter().map(|v| base_from_model * v).collect();
        let (lowest, highest) = points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), p| (lo.min(p.z), hi.max(p.z)));
        let centre = base_from_model.translation.vector.xy();
        let radius = points.iter().map(|p| (p.coords.xy() - centre).norm()).fold(0.0, f64::max);
        Extent { lowest, highest, centre, radius }
    }
}

/// A part rests on what lies within this of its lowest point, metres. Over tuning seeds
/// 2001-2020 and 3001-3020 (704 readings), the lowest points of parts on the table lay 3 mm
/// below its top to 1 mm above it (the calibration's error is about a millimetre, the
/// matcher's a few tenths); of the 12 readings beyond, 4 lay 5-8 mm above it, among them a
/// wedge read 20 mm from where it lay (seed 3005, picked for nothing at 8 mm) and a U-channel
/// read as an L-bracket.
const RESTING_M: f64 = 0.004;
/// A part within this (metres) but not within [`RESTING_M`] may rest: it is tried only when no
/// part that rests is left, rather than skipped. On tuning seeds 1-30 (`eval run`, both presets)
/// no reading falls in the band: 0.004 (no such tier), 0.008 and 0.012 clear the same parts
/// (docs/TUNING.md), so the value stands as shown harmless, not as chosen there. (History: the
/// tier was added after a reporting seed, 10002, left a wedge read 4-8 mm high on the table.)
const MAY_REST_M: f64 = 0.008;

/// A located part is taken to lie in a bin when its origin is within this of the bin's
/// footprint, anywhere above its floor.
const BIN_MARGIN_M: f64 = 0.02;

/// The pick request for part `i`: its first grasp and its pose in `cam`, the others as
/// obstacles.
fn pick_spec(located: &[Located], i: usize, bin: &str) -> PickSpec {
    let l = &located[i];
    let (cam_from_gripper, width) = l.grasps.first().copied().unwrap_or((l.cam_from_model, 0.0));
    let cam = |p: &Isometry3<f64>| WirePose::new(Some(Frame::Cam), p);
    PickSpec {
        model: l.model.clone(),
        grasp: WireGrasp::new(cam(&cam_from_gripper), width * 1e3),
        place: PlaceSpec { bin: bin.to_string() },
        object: Some(cam(&l.cam_from_model)),
        obstacles: located
            .iter()
            .enumerate()
            .filter(|(j, _)| *j != i)
            .map(|(_, o)| WireObject { model: o.model.clone(), pose: cam(&o.cam_from_model) })
            .collect(),
        plan_only: false,
    }
}

/// Table 1 of the paper: the time of each MARVIN stage on the transputers, ms.
pub const PAPER_TABLE1_MS: [(&str, f64); 8] = [
    ("Canny", 5500.0),
    ("PMF stereo", 1000.0),
    ("2D geometry", 100.0),
    ("3D geometry", 200.0),
    ("joining", 100.0),
    ("model matching", 1600.0),
    ("overheads", 1000.0),
    ("total", 10_000.0),
];

/// One row of Table 1 as measured here.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Table1Row {
    pub stage: &'static str,
    /// Median over the cycles, ms: processor time summed over the 8 slices for the front end's
    /// stages, wall time for the rest.
    pub measured_ms: f64,
    pub paper_ms: f64,
}

/// Table 1 from the cycles' stage times (medians), with the slices' parallel efficiency: the
/// processor time of the sliced stages over the slices' wall time times the cores.
pub fn table1(cycles: &[Cycle]) -> (Vec<Table1Row>, f64) {
    let median = |f: &dyn Fn(&Cycle) -> f64| {
        let mut v: Vec<f64> = cycles.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    let stage = |c: &Cycle, names: &[&str]| -> f64 {
        c.timings_ms.iter().filter(|(n, _)| names.contains(n)).map(|(_, ms)| ms).sum()
    };
    let sliced = ["canny", "strings", "rectify", "pmf", "geom2d", "geom3d"];
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
    let measured: [f64; 8] = [
        median(&|c| stage(c, &["canny", "strings"])),
        median(&|c| stage(c, &["rectify", "pmf"])),
        median(&|c| stage(c, &["geom2d"])),
        median(&|c| stage(c, &["geom3d"])),
        median(&|c| stage(c, &["join"])),
        median(&|c| stage(c, &["match"])),
        // Capture and decoding, and the sliced stages' wall time not spent computing.
        median(&|c| stage(c, &["capture"]) + (stage(c, &["slices"]) - stage(c, &sliced) / cores).max(0.0)),
        median(&|c| stage(c, &["capture", "slices", "join", "match"])),
    ];
    let rows = PAPER_TABLE1_MS
        .iter()
        .zip(measured)
        .map(|(&(stage, paper_ms), measured_ms)| Table1Row { stage, measured_ms, paper_ms })
        .collect();
    let efficiency = median(&|c| stage(c, &sliced) / (stage(c, &["slices"]) * cores));
    (rows, efficiency)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block read on the table rests; one read in mid-air or sunk into the table does not;
    /// one read on top of another rests on it.
    #[test]
    fn a_part_rests_on_the_table_or_on_another_part() {
        let library = mesh::Library::load_default().unwrap();
        let block = library.get("block").unwrap();
        let (lo, hi) = block.mesh.vertices.iter().fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v.z), hi.max(v.z)));
        let at = |x: f64, z: f64| Located {
            model: "block".into(),
            cam_from_model: Isometry3::translation(x, 0.0, z),
            support: 0.1,
            support_fraction: 0.5,
            scene_lines: vec![],
            image_support: 0.9,
            grasps: vec![],
        };
        // The base frame is the camera's here; the table's top at height 0.
        let base = Isometry3::identity();
        let on_table = at(0.0, -lo);
        let judged = |parts: &[Located]| resting(parts, &library, &base, Some(0.0), RESTING_M);
        assert_eq!(judged(std::slice::from_ref(&on_table)), [true]);
        assert_eq!(judged(&[at(0.0, -lo + 0.03)]), [false], "in mid-air");
        assert_eq!(judged(&[at(0.0, -lo - 0.02)]), [false], "in the table");
        let stacked = at(0.01, (hi - lo) - lo);
        assert_eq!(judged(&[on_table.clone(), stacked.clone()]), [true, true]);
        assert_eq!(judged(&[at(0.5, -lo), stacked]), [true, false], "over nothing");
        assert_eq!(judged(&[at(0.0, -lo + 0.006)]), [false], "6 mm up");
        assert_eq!(resting(&[at(0.0, -lo + 0.006)], &library, &base, Some(0.0), MAY_REST_M), [true], "may rest");
        assert_eq!(resting(&[at(0.0, 0.5)], &library, &base, None, RESTING_M), [true], "no table known");
    }

    /// The highest part goes first, of parts as high the best supported; but a part read from
    /// one 3D line waits for those read from more, however high it lies; parts in a bin, or
    /// failed twice at about the same pose, are not tried.
    #[test]
    fn parts_are_tried_highest_first_and_those_on_one_line_last() {
        let at = |z: f64, support: f64, lines: usize| Located {
            model: "block".into(),
            cam_from_model: Isometry3::translation(z, 0.0, z),
            support,
            support_fraction: support,
            scene_lines: (0..lines).collect(),
            image_support: 0.9,
            grasps: vec![],
        };
        let base = Isometry3::identity();
        let located = [at(0.02, 0.3, 4), at(0.05, 0.2, 3), at(0.10, 0.05, 1), at(0.02, 0.4, 3)];
        assert_eq!(pick_order((&located, &[]), &base, &[], &[]), [1, 3, 0, 2]);
        let failed = vec![("block".to_string(), located[1].cam_from_model); MAX_TRIES];
        assert_eq!(pick_order((&located, &[]), &base, &[], &failed), [3, 0, 2]);
        let bin =
            crate::protocol::BinBox { name: "bin".into(), centre_base_m: [0.02, 0.0, 0.0], size_m: [0.01, 0.01, 0.01] };
        assert_eq!(pick_order((&located, &[]), &base, std::slice::from_ref(&bin), &[]), [1, 2]);
    }

    /// A reading that matches little of its model along 3D lines, or runs along edgels for
    /// little of its wireframe, waits for the surer ones, however high it lies.
    #[test]
    fn readings_on_weak_evidence_wait_for_the_sure_ones() {
        let at = |z: f64, support_fraction: f64, image_support: f64| Located {
            model: "block".into(),
            cam_from_model: Isometry3::translation(z, 0.0, z),
            support: support_fraction,
            support_fraction,
            scene_lines: (0..4).collect(),
            image_support,
            grasps: vec![],
        };
        let base = Isometry3::identity();
        let located = [
            at(0.10, 0.3, MIN_IMAGE_TO_GO_FIRST - 0.01),
            at(0.08, MIN_SUPPORT_TO_GO_FIRST - 0.01, 0.9),
            at(0.02, 0.3, 0.9),
            at(0.05, MIN_SUPPORT_TO_GO_FIRST, MIN_IMAGE_TO_GO_FIRST),
        ];
        assert_eq!(pick_order((&located, &[]), &base, &[], &[]), [3, 2, 0, 1]);
    }

    /// A reading a turn of its part fits as well waits for the sure ones, however high it lies
    /// and however well supported.
    #[test]
    fn readings_in_doubt_wait_for_the_sure_ones() {
        let at = |z: f64| Located {
            model: "block".into(),
            cam_from_model: Isometry3::translation(z, 0.0, z),
            support: 0.4,
            support_fraction: 0.4,
            scene_lines: (0..4).collect(),
            image_support: 0.9,
            grasps: vec![],
        };
        let (base, located) = (Isometry3::identity(), [at(0.02), at(0.10), at(0.05)]);
        assert_eq!(pick_order((&located, &[]), &base, &[], &[]), [1, 2, 0]);
        assert_eq!(pick_order((&located, &[false, true, false]), &base, &[], &[]), [2, 0, 1]);
    }
}
