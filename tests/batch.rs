//! The `eval` verbs as batches at scale: shards merged, scenes run two at a time, and (`eval
//! run`) a batch killed in the middle and resumed, each giving the figures of one process over
//! the same seeds.
//! On tuning seeds 1-4 of the ideal world, with the cameras and the hand-eye transform from files
//! (`tests/fixtures/ideal_seed3/`: `marvin calibrate cameras worlds/ideal/widgets.toml --seed 3`,
//! then `marvin calibrate ... --cameras` through them), as a cluster's shards share them.

mod common;

use common::{FIXTURES, eval_run, figures, marvin, ok, scratch, without};
use serde_json::Value;
use std::process::Stdio;
use std::time::{Duration, Instant};

#[test]
fn shards_merged_jobs_and_a_resumed_batch_give_one_processs_figures() {
    let dir = scratch("batch_run");
    let p = |name: &str| dir.join(name).display().to_string();
    let whole = figures(ok(eval_run(&[]).output().unwrap()));
    assert_eq!(whole["scenes"], 4);

    // Four shards, one scene each, merged.
    for k in 1..=4 {
        ok(eval_run(&["--shard", &format!("{k}/4"), "--out", &p(&format!("s{k}.jsonl"))]).output().unwrap());
    }
    let shards: Vec<String> = (1..=4).map(|k| p(&format!("s{k}.jsonl"))).collect();
    let mut merge = marvin();
    merge.args(["eval", "merge", "--json"]).args(&shards);
    assert_eq!(figures(ok(merge.output().unwrap())), whole, "four shards merged");

    // Two scenes at a time.
    assert_eq!(figures(ok(eval_run(&["--jobs", "2"]).output().unwrap())), whole, "--jobs 2");

    // Killed once its first scene is recorded, then resumed.
    let out = p("killed.jsonl");
    let mut child = eval_run(&["--out", &out]).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    let clock = Instant::now();
    while std::fs::read_to_string(&out).map_or(0, |t| t.lines().count()) < 1 {
        assert!(clock.elapsed() < Duration::from_secs(300), "no scene recorded");
        std::thread::sleep(Duration::from_millis(50));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let before = std::fs::read_to_string(&out).unwrap().lines().count();
    assert!(before < 4, "killed before the end ({before} scenes recorded)");
    let resumed = figures(ok(eval_run(&["--out", &out, "--resume"]).output().unwrap()));
    assert_eq!(resumed, whole, "killed after {before} scenes and resumed");
    let mut merge = marvin();
    merge.args(["eval", "merge", "--json", &out]);
    assert_eq!(figures(ok(merge.output().unwrap())), whole, "the resumed file merged alone");

    // What merge refuses, saying why.
    let mut merge = marvin();
    let o = merge.args(["eval", "merge", &shards[0], &shards[2]]).output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("missing [2, 4]"), "{e}");
    let twice = [shards[0].clone(), shards[0].clone(), shards[1].clone(), shards[2].clone(), shards[3].clone()];
    let o = marvin().args(["eval", "merge"]).args(twice).output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("more than once [1]"), "{e}");
    let other = p("other_version.jsonl");
    let text = std::fs::read_to_string(&shards[3]).unwrap();
    let mut record: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    record["version"] = Value::from("0.0.0 (elsewhere)");
    std::fs::write(&other, format!("{record}\n")).unwrap();
    let o = marvin().args(["eval", "merge", &shards[0], &shards[1], &shards[2], &other]).output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("code versions"), "{e}");
    // A file that holds records is not appended to without --resume.
    let o = eval_run(&["--out", &out]).output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("--resume"), "{e}");
}

#[test]
fn shard_auto_without_a_scheduler_is_refused_naming_what_it_looked_for() {
    let o = eval_run(&["--shard", "auto"])
        .env_remove("SLURM_ARRAY_TASK_ID")
        .env_remove("JOB_COMPLETION_INDEX")
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"), "{e}");
    let o = eval_run(&["--shard", "5/4"]).output().unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("K must be 1 to N"));
}

/// `shards` shards of `args` merged, and `args` two scenes at a time, give the figures of `args`
/// in one process, but for the wall-time keys `timing`; `count` is the summary's scene count key.
fn shards_and_jobs_agree(name: &str, args: &[&str], shards: usize, timing: &str, count: (&str, u64)) {
    let dir = scratch(name);
    let p = |file: &str| dir.join(file).display().to_string();
    let verb = |extra: &[&str]| {
        let mut c = marvin();
        c.args(args).arg("--json").args(extra);
        c
    };
    let without_time = |v: Value| without(v, &[timing]);
    let whole = without_time(ok(verb(&[]).output().unwrap()));
    assert_eq!(whole[count.0], count.1);
    let files: Vec<String> = (1..=shards).map(|k| p(&format!("s{k}.jsonl"))).collect();
    for (k, file) in files.iter().enumerate() {
        ok(verb(&["--shard", &format!("{}/{shards}", k + 1), "--out", file]).output().unwrap());
    }
    let o = marvin().args(["eval", "merge", "--json"]).args(&files).output().unwrap();
    assert_eq!(without_time(ok(o)), whole, "{shards} shards merged");
    assert_eq!(without_time(ok(verb(&["--jobs", "2"]).output().unwrap())), whole, "--jobs 2");
}

/// `eval locate` batched the same way (tuning seeds 1-4, the table placed by the shared
/// hand-eye file).
#[test]
fn eval_locate_shards_merged_and_jobs_give_one_processs_figures() {
    let hand_eye = format!("{FIXTURES}/hand_eye.json");
    let args = ["eval", "locate", "worlds/ideal/widgets.toml", "--scenes", "4", "--seed", "1", "--hand-eye", &hand_eye];
    shards_and_jobs_agree("batch_locate", &args, 4, "match_ms_median", ("scenes", 4));
}

/// `eval pick` batched the same way (tuning seeds 1-4).
#[test]
fn eval_pick_shards_merged_and_jobs_give_one_processs_figures() {
    let args = ["eval", "pick", "worlds/ideal/widgets.toml", "--trials", "4", "--seed", "1"];
    shards_and_jobs_agree("batch_pick", &args, 4, "wall_s", ("trials", 4));
}

/// `eval vision` batched the same way (tuning seeds 1-4, realistic widgets, the world file's
/// cameras).
#[test]
fn eval_vision_shards_merged_and_jobs_give_one_processs_figures() {
    let args = ["eval", "vision", "worlds/widgets.toml", "--scenes", "4", "--seed", "1"];
    shards_and_jobs_agree("batch_vision", &args, 4, "timings_ms", ("scenes", 4));
}

/// `eval calibrate` (hand-eye, through the shared cameras) batched the same way: a record per
/// trial (tuning seeds 1-2, 8 poses each).
#[test]
fn eval_calibrate_shards_merged_and_jobs_give_one_processs_figures() {
    let cameras = format!("{FIXTURES}/cameras.json");
    let args = ["eval", "calibrate", "worlds/ideal/widgets.toml", "--trials", "2", "--seed", "1", "--poses", "8"];
    let args: Vec<&str> = args.into_iter().chain(["--cameras", &cameras]).collect();
    shards_and_jobs_agree("batch_calibrate", &args, 2, "shard", ("trials", 2));
}

/// `eval calibrate cameras` batched the same way (tuning seeds 1-2, 8 board poses each).
#[test]
fn eval_calibrate_cameras_shards_merged_and_jobs_give_one_processs_figures() {
    let args =
        ["eval", "calibrate", "cameras", "worlds/ideal/widgets.toml", "--trials", "2", "--seed", "1", "--poses", "8"];
    shards_and_jobs_agree("batch_calibrate_cameras", &args, 2, "shard", ("trials", 2));
}
