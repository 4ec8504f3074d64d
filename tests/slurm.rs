//! A real scheduler: a one-node Slurm cluster brought up on this machine (`tests/slurm/cluster.sh`:
//! munge, slurmctld, slurmd), the repository's job array script (`deploy/slurm/eval.sbatch`)
//! submitted as 4 shards of `eval run`, the shards' records merged, against one process over the
//! same seeds (tuning seeds 1-4 of the ideal world, the calibration from `tests/fixtures/`).
//!
//! Needs Debian's `slurm-wlm` and `munge`, and root. `.ci/run` installs them and sets
//! `MARVIN_SLURM_TEST=require`; elsewhere, without Slurm, the test says it did not run.

mod common;

use common::{FIXTURES, eval_run, figures, marvin, ok, scratch};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

const CLUSTER: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/slurm/cluster.sh");
const SBATCH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/deploy/slurm/eval.sbatch");

/// A one-node cluster under `dir`, shut down when dropped.
struct Cluster {
    dir: PathBuf,
    conf: String,
}

impl Cluster {
    fn up(dir: &Path) -> Cluster {
        let port = || TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port().to_string();
        let o = Command::new(CLUSTER).arg("up").arg(dir).args([port(), port()]).output().unwrap();
        assert!(o.status.success(), "the cluster did not come up: {}", String::from_utf8_lossy(&o.stderr));
        let conf = String::from_utf8(o.stdout).unwrap().trim().to_string();
        Cluster { dir: dir.to_path_buf(), conf }
    }

    fn command(&self, program: &str) -> Command {
        let mut c = Command::new(program);
        c.env("SLURM_CONF", &self.conf);
        c
    }

    fn logs(&self) -> String {
        let log = self.dir.join("log/slurmctld.log");
        std::fs::read_to_string(&log).unwrap_or_default().lines().rev().take(20).collect::<Vec<_>>().join("\n")
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let _ = Command::new(CLUSTER).arg("down").arg(&self.dir).status();
    }
}

fn slurm_installed() -> bool {
    ["munged", "slurmctld", "slurmd", "sbatch"]
        .iter()
        .all(|t| Command::new("sh").args(["-c", &format!("command -v {t}")]).output().is_ok_and(|o| o.status.success()))
}

#[test]
fn a_slurm_job_array_of_four_shards_merges_to_one_processs_figures() {
    if !slurm_installed() {
        let required = std::env::var("MARVIN_SLURM_TEST").is_ok_and(|v| v == "require");
        assert!(!required, "MARVIN_SLURM_TEST=require, but Slurm is not installed (apt-get install slurm-wlm munge)");
        eprintln!("not run: no Slurm on this machine (apt-get install slurm-wlm munge, or run .ci/run)");
        return;
    }
    let dir = scratch("slurm");
    let cluster = Cluster::up(&dir.join("cluster"));
    let results = dir.join("results");
    let (cameras, hand_eye) = (format!("{FIXTURES}/cameras.json"), format!("{FIXTURES}/hand_eye.json"));
    let mut submit = cluster.command("sbatch");
    submit
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .env("MARVIN", env!("CARGO_BIN_EXE_marvin"))
        .env("MARVIN_RESULTS", &results)
        .args(["--wait", "--array=0-3", "--parsable"])
        .arg(format!("--output={}/task-%a.out", dir.display()))
        .arg(SBATCH)
        .args(["run", "worlds/ideal/widgets.toml", "--scenes", "4", "--seed", "1"])
        .args(["--cameras", &cameras, "--hand-eye", &hand_eye]);
    let clock = Instant::now();
    let mut child = submit.spawn().unwrap();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if clock.elapsed() > Duration::from_secs(900) {
            let _ = child.kill();
            panic!("the job array did not end in 15 min:\n{}", cluster.logs());
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    let task_output = |k: usize| std::fs::read_to_string(dir.join(format!("task-{k}.out"))).unwrap_or_default();
    assert!(
        status.success(),
        "the job array failed:\n{}\n{}",
        (0..4).map(task_output).collect::<Vec<_>>().join("\n"),
        cluster.logs()
    );

    // Each task ran its own shard: one scene each, every seed once.
    let shards: Vec<PathBuf> = (0..4).map(|k| results.join(format!("shard-{k}.jsonl"))).collect();
    let mut seeds: Vec<u64> = Vec::new();
    for (k, file) in shards.iter().enumerate() {
        let text = std::fs::read_to_string(file).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let records: Vec<serde_json::Value> = text.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
        assert_eq!(records.len(), 1, "task {k} recorded one scene");
        seeds.push(records[0]["seed"].as_u64().unwrap());
        let printed = ok_text(&task_output(k));
        assert_eq!(printed["shard"], format!("{}/4", k + 1), "task {k} ran shard {} of 4", k + 1);
    }
    seeds.sort();
    assert_eq!(seeds, [1, 2, 3, 4]);

    let mut merge = marvin();
    merge.args(["eval", "merge", "--json"]).args(&shards);
    let merged = figures(ok(merge.output().unwrap()));
    let whole = figures(ok(eval_run(&[]).output().unwrap()));
    assert_eq!(merged, whole, "the job array's shards merged against one process");
}

/// The summary line a task printed (its last line of JSON), whatever it logged before.
fn ok_text(output: &str) -> serde_json::Value {
    let line = output.lines().rev().find(|l| l.starts_with('{')).unwrap_or_else(|| panic!("no summary in {output}"));
    serde_json::from_str(line).unwrap()
}
