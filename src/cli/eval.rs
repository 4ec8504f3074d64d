//! `marvin eval`: seeded scenes run through the pipeline and compared with ground truth. Every
//! fraction counted over trials (not `coverage`, a length) comes with `<key>_ci95`, its 95%
//! Wilson interval ([`marvin::eval::wilson95`]).

use super::scene::canny_params;
use clap::Subcommand;
use std::path::PathBuf;

#[derive(Subcommand)]
pub enum EvalTarget {
    /// The vision front end: render, run, compare with ground truth.
    ///
    /// JSON keys (each fraction also as `<key>_ci95`, its 95% Wilson interval) so far: `disparity_within_0_5px` and `wrong_matches` (fractions of matched
    /// edgels whose disparity is within 0.5 px of the true one / more than 2 px off; at an
    /// occluding boundary the true disparity is the nearer surface's), `matches_per_scene`,
    /// `endpoint_err_mm_median` and `_p90` (3D line ends from the nearest true feature edge),
    /// `coverage` (of visible feature-edge length in pieces >= 20 px long in the image, the part
    /// a 3D line runs along within 3 mm and 10 deg), `lines3d_off_edges` (share of the 3D lines
    /// whose middle lies more than 5 mm from every true feature edge), `lines3d_off_edges_on_table`
    /// (of all 3D lines, those off every edge with both ends within 5 mm of the true table top:
    /// shadows' edges and the table's texture), `lines3d_on_table` (all with both ends there,
    /// parts' bottom edges included; these three count the 3D lines the front end kept),
    /// `set_apart` (the lines set apart as shadows or texture, `front_end::soft_edges`:
    /// `per_scene`, `off_edges` the share of them off every true edge, `of_off_edges_on_table`
    /// the share of the table's off-edge lines set apart; without `--hand-eye` the table's top
    /// is taken from the 3D lines to set them apart), `table` (what placed it: `--hand-eye`, or none),
    /// `timings_ms` (median per stage: with slices,
    /// each stage's processor time summed over the slices, then `slices` and `join` wall time),
    /// `unsettled_scenes` (scenes that did not come to rest, evaluated anyway), `left_edgels`
    /// (what became of the left edgels with a true disparity, as fractions: matched within 0.5
    /// px or off; refused by a test of PMF's candidate selection -- `NearRaster`, `NoPartner`
    /// (no right edgel there), `OutOfRange`, `ContrastSign`, `ContrastRatio`, `Sides`,
    /// `Orientation`; or, with a true candidate, `candidate_unmatched` by PMF, `rival_won`, or
    /// `dropped_after_pmf` (right-string continuity, or on no 3D line)).
    Vision {
        world: PathBuf,
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
        scenes: u64,
        /// First seed; scene k uses seed + k.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(..=super::args::MAX_FIRST_SEED))]
        seed: u64,
        /// Slices of the front end (1: whole images).
        #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u16).range(1..=64))]
        slices: u16,
        /// Edgels as the blur places them, not deblurred (`CannyParams::deblur`: each edgel
        /// beside a parallel step a few pixels away placed where its own step lies; docs/TUNING.md,
        /// "Edgels beside narrow faces"), for comparison.
        #[arg(long)]
        no_deblur: bool,
        #[arg(long)]
        json: bool,
        /// Vision sees through these measured cameras (`marvin calibrate cameras`' cameras.json,
        /// placed where the left camera truly stands: evaluation takes the hand-eye calibration's
        /// part as known) instead of the world file's.
        #[arg(long)]
        cameras: Option<PathBuf>,
        /// The hand-eye calibration (`marvin calibrate`'s file) that places the table, as `marvin
        /// run` places it: PMF then searches no disparity under the table's top. Without it the
        /// front end searches the constant workspace depths, as where no table is known.
        #[arg(long)]
        hand_eye: Option<PathBuf>,
        #[command(flatten)]
        batch: BatchArgs,
    },
    /// Seeded end-to-end runs (`marvin run`), one calibration on the first seed's scene shared
    /// by all, each scene's outcome judged from the simulation's truth afterwards.
    ///
    /// JSON keys (each fraction also as `<key>_ci95`, its 95% Wilson interval): `cleared_fraction` (objects in the bin at the end of all objects on the table at
    /// the start), `pick_success_rate` (placed of picks tried, every attempt counted),
    /// `first_attempt_success_rate` (of the first pick at each object, which object from the
    /// truth afterwards, the share placed), `attempts_per_object` (picks per object placed),
    /// `wrong_model_picks` (picks at a pose where no object of the model chosen lay within
    /// 20 mm) and `wrong_picks` (each: seed, cycle, model, support, image support, outcome,
    /// the nearest object of its model and of any model), `cycles_mean`, `cycle_s_mean` (wall), `vision_cycle_ms_median` (front end and
    /// matcher), `failures` (by kind, every attempt, those later retried included),
    /// `failed_picks` (each: seed, cycle, model, outcome, where the part came to rest, and
    /// `grip_past_com_mm`, how far the fingertips reached past its centre of mass),
    /// `stopped_by`, `pushing_picks` and `pushing_placed` (picks planned with the neighbours left
    /// out, where every part was blocked by another, and of those placed), `calibration_error`,
    /// `unsettled_scenes`.
    Run {
        world: PathBuf,
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
        scenes: u64,
        /// First seed; scene k uses seed + k.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(..=super::args::MAX_FIRST_SEED))]
        seed: u64,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        batch: BatchArgs,
        /// Measured cameras to share (`marvin calibrate cameras`), instead of calibrating first.
        #[arg(long)]
        cameras: Option<PathBuf>,
        /// A hand-eye calibration to share (`marvin calibrate`), instead of calibrating first.
        #[arg(long)]
        hand_eye: Option<PathBuf>,
    },
    /// The matcher on stereo pairs imaged anywhere, judged against their scenes' truth: DIR holds
    /// one folder per scene with `left.png`, `right.png` and the `scene.json` (and
    /// `depth_left.png`) of `marvin render`, the images perhaps replaced by another renderer's
    /// or a real rig's. Each pair is read as `marvin locate --left --right --cameras` reads it
    /// (the table from its own 3D lines) and counted as `eval locate` counts: the same JSON
    /// keys, and `scenes_read` (per folder: its seed, located, in view, false reports, reports).
    Pairs {
        dir: PathBuf,
        /// The cameras the pairs were taken with (`marvin calibrate cameras`' cameras.json, or
        /// a scene.json).
        #[arg(long)]
        cameras: PathBuf,
        /// Also judge which reports are in doubt, as `eval locate --doubt` does; adds
        /// `in_doubt` (right and false reports in doubt) and marks each false report.
        #[arg(long)]
        doubt: bool,
        #[arg(long)]
        json: bool,
    },
    /// Merge the per-scene records (`--out` files) of a batch's shards into the summary one
    /// process over the whole range prints; refuses records of different verbs, worlds, ranges
    /// or code versions, and says which seeds are missing or there twice.
    Merge {
        #[arg(required = true)]
        files: Vec<PathBuf>,
        #[arg(long)]
        json: bool,
    },
    /// Seeded hand-eye calibrations (each on its own scene, with its own poses and sensor noise),
    /// each through a robot server started here, against the simulation's truth; through
    /// cameras calibrated once from the board first (or `--cameras`).
    ///
    /// JSON keys (each fraction also as `<key>_ci95`, its 95% Wilson interval): `translation_err_mm_median`, `_p90`, `rotation_err_deg_median`, `_p90` (the
    /// solved `cam_from_base` against the true one), `sightings_used_fraction` (poses whose
    /// sighting the solve used), `flag_creep_mm_max`, `_median` (how far the flag moved in the
    /// jaws between the first and last sighting, from the physics), `flag_turn_deg_max`,
    /// `_median` (how far it turned), `failed`, `unsettled_scenes`.
    #[command(args_conflicts_with_subcommands = true, subcommand_negates_reqs = true)]
    Calibrate {
        /// `marvin eval calibrate cameras WORLD`: the camera calibration (see its --help).
        #[command(subcommand)]
        what: Option<EvalCalibrateWhat>,
        #[arg(required = true)]
        world: Option<PathBuf>,
        #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
        trials: u64,
        /// First seed; trial k uses seed + k.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(..=super::args::MAX_FIRST_SEED))]
        seed: u64,
        /// Poses per calibration.
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u16).range(3..=500))]
        poses: u16,
        /// See through these measured cameras (`marvin calibrate cameras`' cameras.json);
        /// without it the cameras are calibrated once, on the first seed's scene.
        #[arg(long)]
        cameras: Option<PathBuf>,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        batch: BatchArgs,
    },
    /// Physical picks with the simulated arm, planned from true poses, judged from the physics.
    ///
    /// Clutter: each of `--trials` seeded scenes is cleared object by object, the highest first;
    /// an object whose pick fails is tried again once the others have gone (3 passes at most).
    /// JSON keys (each fraction also as `<key>_ci95`, its 95% Wilson interval): `cleared_fraction` (objects in the bin at the end, of all objects; this was
    /// `success_rate`), `first_attempt_success_rate` (objects placed by their first pick),
    /// `pick_success_rate` (placed, of every pick tried), `attempts_per_object`, `failures`
    /// (every failed pick by kind, those later retried included: `unplanned`, `miss`, `slip`,
    /// `drop`, `outside bin`, `wrong part`), `failures_left_on_table` (the last failure of each object not
    /// cleared). Single: each library model but the calibration flag alone, dropped at
    /// `--trials` seeded poses over the clutter region, picked once: `single_success_rate`,
    /// `single_by_model`, `single_failures`. Also `objects`, `picks`, `unsettled_scenes`
    /// (scenes that did not come to rest, used anyway), `simulated_s`, `wall_s`.
    Pick {
        world: PathBuf,
        #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
        trials: u64,
        /// First seed; trial k uses seed + k.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(..=super::args::MAX_FIRST_SEED))]
        seed: u64,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        batch: BatchArgs,
    },
    /// The model matcher on the front end's 3D lines: render, locate, compare with ground truth.
    ///
    /// JSON keys (each fraction also as `<key>_ci95`, its 95% Wilson interval): `located_fraction` (of objects with >= 30% of their feature-edge length
    /// visible), `pos_err_mm_median`, `pos_err_mm_p90`, `rot_err_deg_median` (of correct reports,
    /// over each model's symmetries; correct = within 10 mm and 5 deg), `false_positive_fraction`
    /// (of all reports), `match_ms_median`, `located_by_model`, `unsettled_scenes`, `missed`
    /// (each eligible object not located: seed, model, visible share, and `at_truth`, the
    /// matcher's own measures at its true pose, judged afterwards: share of the wireframe along
    /// 3D lines, model lines seen, share along each image's edgels), `false_reports` (each report
    /// that matched no object: seed, model, support, the nearest object of its model and of any
    /// (id, mm, deg), `world_m`, where it put the model's origin in the world, and
    /// `as_reported`, the same measures as `at_truth` at its own pose).
    Locate {
        world: PathBuf,
        #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
        scenes: u64,
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(..=super::args::MAX_FIRST_SEED))]
        seed: u64,
        /// Edgels as the blur places them, not deblurred (`CannyParams::deblur`: each edgel
        /// beside a parallel step a few pixels away placed where its own step lies; docs/TUNING.md,
        /// "Edgels beside narrow faces"), for comparison.
        #[arg(long)]
        no_deblur: bool,
        #[arg(long)]
        json: bool,
        /// Vision sees through these measured cameras (as for `eval vision`).
        #[arg(long)]
        cameras: Option<PathBuf>,
        /// The hand-eye calibration (`marvin calibrate`'s file) that places the table, as `marvin
        /// run` places it; without it one is made first, through the cameras vision sees by, on
        /// the first seed's scene.
        #[arg(long)]
        hand_eye: Option<PathBuf>,
        /// The matcher takes the table's top from each scene's own 3D lines, as `marvin locate
        /// --left --right` does where no cell layout places it, instead of a hand-eye
        /// calibration; adds `table_from_images` (the share of scenes where a top was found,
        /// and its error against the true top at the workspace's centre, judged afterwards).
        #[arg(long, conflicts_with = "hand_eye")]
        table_from_images: bool,
        /// Also judge which reports are in doubt, a turn of the part fitting them as well in
        /// both images (`vision::matcher::polish::doubt`, as `marvin run` judges the part it
        /// would pick); adds `in_doubt` (right and false reports in doubt). Costs a refit of
        /// every turn of every report.
        #[arg(long)]
        doubt: bool,
        #[command(flatten)]
        batch: BatchArgs,
    },
}

/// How a batch of seeded scenes is run at scale (`docs/SCALE.md`).
#[derive(clap::Args, Debug)]
pub struct BatchArgs {
    /// Run shard K of N of the scenes (those whose index from the first, counting from 0,
    /// leaves K - 1 divided by N), or `auto`: the index a Slurm job array
    /// (SLURM_ARRAY_TASK_ID) or a Kubernetes Indexed Job (JOB_COMPLETION_INDEX, with
    /// JOB_COMPLETIONS set) gives.
    #[arg(long)]
    shard: Option<String>,
    /// Append one JSON line per scene to this file as the scene ends (for `eval merge`).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Skip the scenes already in --out's file and carry on.
    #[arg(long, requires = "out")]
    resume: bool,
    /// Scenes run at once; the figures do not depend on it.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=64))]
    jobs: u64,
}

impl BatchArgs {
    /// The batch of `scenes` from `seed` on `world`, its shard read from the scheduler for `auto`.
    fn batch(self, world: PathBuf, scenes: u64, seed: u64, json: bool) -> anyhow::Result<super::batch::Batch> {
        let env = |k: &str| std::env::var(k).ok();
        let shard = match &self.shard {
            Some(s) => marvin::eval::batch::Shard::parse(s, &env)?,
            None => marvin::eval::batch::Shard::ALL,
        };
        let BatchArgs { out, resume, jobs, .. } = self;
        Ok(super::batch::Batch { world, scenes, seed, json, shard, out, resume, jobs: jobs as usize })
    }
}

/// What `marvin eval calibrate` evaluates besides the hand-eye calibration.
#[derive(Subcommand, Debug)]
pub enum EvalCalibrateWhat {
    /// Seeded camera calibrations (`marvin calibrate cameras`), each against the cameras as
    /// built: medians and 90th percentiles of the focal lengths' relative error (`f_rel`), the
    /// principal points' (`principal_point_px`), the distortion field's worst difference over
    /// the image (`distortion_field_px_max`), `baseline_mm`, `right_position_mm`,
    /// `rotation_deg`, `rms_px`; `views_used_median`, `board_lost_on_the_way`, `failed`.
    Cameras {
        world: PathBuf,
        #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=super::args::MAX_COUNT))]
        trials: u64,
        /// First seed; trial k uses seed + k.
        #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(..=super::args::MAX_FIRST_SEED))]
        seed: u64,
        /// Board poses per calibration.
        #[arg(long, default_value_t = 24, value_parser = clap::value_parser!(u16).range(3..=500))]
        poses: u16,
        #[arg(long)]
        json: bool,
        #[command(flatten)]
        batch: BatchArgs,
    },
}

pub fn run(target: EvalTarget) -> anyhow::Result<()> {
    match target {
        EvalTarget::Vision { world, scenes, seed, slices, no_deblur, json, cameras, hand_eye, batch } => {
            let sources =
                super::eval_vision::Sources { cameras, hand_eye, deblur: !no_deblur, slices: slices as usize };
            super::eval_vision::eval(&batch.batch(world, scenes, seed, json)?, &sources)
        }
        EvalTarget::Locate {
            world,
            scenes,
            seed,
            no_deblur,
            json,
            cameras,
            hand_eye,
            table_from_images,
            doubt,
            batch,
        } => {
            let canny = canny_params(!no_deblur);
            let sources = super::eval_locate::Sources { cameras, hand_eye, table_from_images, canny, doubt };
            super::eval_locate::eval(&batch.batch(world, scenes, seed, json)?, &sources)
        }
        EvalTarget::Pick { world, trials, seed, json, batch } => {
            super::eval_pick::run(&batch.batch(world, trials, seed, json)?)
        }
        EvalTarget::Run { world, scenes, seed, json, batch, cameras, hand_eye } => {
            let shared = super::eval_run_batch::Shared { cameras, hand_eye };
            super::eval_run_batch::eval(&batch.batch(world, scenes, seed, json)?, &shared)
        }
        EvalTarget::Merge { files, json } => merge(&files, json),
        EvalTarget::Pairs { dir, cameras, doubt, json } => super::eval_pairs::run(&dir, &cameras, (doubt, json)),
        EvalTarget::Calibrate {
            what: Some(EvalCalibrateWhat::Cameras { world, trials, seed, poses, json, batch }),
            ..
        } => super::eval_calibrate::cameras(&batch.batch(world, trials, seed, json)?, poses as usize),
        EvalTarget::Calibrate { what: None, world, trials, seed, poses, cameras, json, batch } => {
            let world = world.expect("clap requires the world without a subcommand");
            super::eval_calibrate::hand_eye(&batch.batch(world, trials, seed, json)?, poses as usize, cameras)
        }
    }
}

/// `marvin eval merge`: the records of every shard, checked to be one whole batch, summarised.
fn merge(files: &[PathBuf], json: bool) -> anyhow::Result<()> {
    let mut records = Vec::new();
    for f in files {
        records.extend(marvin::eval::batch::read_records(f)?);
    }
    let records = marvin::eval::batch::check_batch(records)?;
    let all = marvin::eval::batch::Shard::ALL;
    match records[0].verb.as_str() {
        "run" => super::batch::print_report(super::eval_run_batch::summarise(&records)?, all, json),
        "locate" => super::batch::print_report(super::eval_locate::summarise(&records)?, all, json),
        "pick" => super::batch::print_report(super::eval_pick::summarise(&records)?, all, json),
        "vision" => super::batch::print_report(super::eval_vision::summarise(&records)?, all, json),
        "calibrate" => super::batch::print_report(super::eval_calibrate::summarise_hand_eye(&records)?, all, json),
        "calibrate-cameras" => {
            super::batch::print_report(super::eval_calibrate::summarise_cameras(&records)?, all, json)
        }
        other => anyhow::bail!("records of `eval {other}`: not records this version of marvin writes"),
    }
}
