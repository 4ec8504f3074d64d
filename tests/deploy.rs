//! The cluster recipes (`docs/SCALE.md`) hold together where no container engine or cluster
//! runs: the image's files are enough to run a world, the build context keeps what the build
//! needs, and the Kubernetes Indexed Job's command, in the image's layout, runs its shard.
//! (`tests/slurm.rs` runs the Slurm recipe on a real one-node cluster.)

mod common;

use common::{FIXTURES, scratch};
use std::path::{Path, PathBuf};
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

fn read(path: &str) -> String {
    std::fs::read_to_string(Path::new(ROOT).join(path)).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The sources the Dockerfile's last stage copies from the build context, and where they go.
fn runtime_copies() -> Vec<(String, String)> {
    let dockerfile = read("Dockerfile");
    let last_stage = dockerfile.rsplit("\nFROM ").next().unwrap();
    last_stage
        .lines()
        .filter_map(|l| l.strip_prefix("COPY "))
        .filter(|l| !l.starts_with("--from"))
        .map(|l| {
            let words: Vec<&str> = l.split_whitespace().collect();
            assert_eq!(words.len(), 2, "COPY SOURCE DEST: {l}");
            (words[0].to_string(), words[1].to_string())
        })
        .collect()
}

/// The image's working directory (`WORKDIR` of the last stage).
fn image_workdir() -> String {
    let dockerfile = read("Dockerfile");
    let last_stage = dockerfile.rsplit("\nFROM ").next().unwrap();
    last_stage.lines().filter_map(|l| l.strip_prefix("WORKDIR ")).next_back().expect("a WORKDIR").trim().to_string()
}

/// The environment the Dockerfile's last stage sets (`ENV KEY=VALUE`), its absolute paths moved
/// under `dir` as [`image_layout`] moves the files.
fn image_env(dir: &Path) -> Vec<(String, String)> {
    let dockerfile = read("Dockerfile");
    let last_stage = dockerfile.rsplit("\nFROM ").next().unwrap();
    last_stage
        .lines()
        .filter_map(|l| l.strip_prefix("ENV "))
        .map(|l| {
            let (key, value) = l.trim().split_once('=').expect("ENV KEY=VALUE");
            let value = match value.strip_prefix('/') {
                Some(path) => dir.join(path).display().to_string(),
                None => value.to_string(),
            };
            (key.to_string(), value)
        })
        .collect()
}

/// A copy of the image's files (`/opt/marvin` and the like) under `dir`: where the image's
/// working directory is.
fn image_layout(dir: &Path) -> PathBuf {
    for (source, dest) in runtime_copies() {
        let to = dir.join(dest.trim_start_matches('/'));
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        let status = Command::new("cp").arg("-r").arg(Path::new(ROOT).join(&source)).arg(&to).status().unwrap();
        assert!(status.success(), "copy {source}");
    }
    dir.join(image_workdir().trim_start_matches('/'))
}

#[test]
fn the_build_context_keeps_what_the_build_needs() {
    let ignored: Vec<String> = read(".dockerignore")
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .map(String::from)
        .collect();
    let manifest = read("Cargo.toml");
    let members = manifest.lines().find(|l| l.starts_with("members")).expect("workspace members");
    let mut needed: Vec<String> = members.split('"').skip(1).step_by(2).map(String::from).collect();
    needed.extend(["Cargo.toml", "Cargo.lock", "build.rs", "src", "worlds", "urdf"].map(String::from));
    for n in &needed {
        assert!(Path::new(ROOT).join(n).exists(), "{n} is in the repository");
        assert!(!ignored.iter().any(|i| i == n || n.starts_with(&format!("{i}/"))), ".dockerignore drops {n}");
    }
    assert!(ignored.iter().any(|i| i == "target"), "the build context leaves out target/");
}

/// The image's files and environment, and nothing of the checkout the binary was built in.
#[test]
fn the_images_files_run_a_world() {
    let dir = scratch("image_files");
    let workdir = image_layout(&dir);
    let env = image_env(&dir);
    // Else the binary reads the models of the checkout it was built in, which no image holds.
    let models = env.iter().find(|(k, _)| k == "MARVIN_MODELS").expect("the image names its model folder");
    assert!(Path::new(&models.1).starts_with(&dir), "the image's model folder is in the image");
    let hand_eye = format!("{FIXTURES}/hand_eye.json");
    let o = Command::new(env!("CARGO_BIN_EXE_marvin"))
        .current_dir(&workdir)
        .envs(env)
        .args(["eval", "locate", "worlds/ideal/widgets.toml", "--scenes", "1", "--seed", "1", "--json"])
        .args(["--hand-eye", &hand_eye])
        .output()
        .unwrap();
    assert!(o.status.success(), "in the image's layout: {}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["scenes"], 1);
}

/// The value of the first `key: value` line under the manifest's Job.
fn field<'a>(job: &'a str, key: &str) -> &'a str {
    let prefix = format!("{key}:");
    job.lines()
        .map(str::trim)
        .find_map(|l| l.strip_prefix(&prefix))
        .unwrap_or_else(|| panic!("no {key} in the manifest"))
        .trim()
        .trim_matches('"')
}

#[test]
fn the_indexed_jobs_command_runs_its_shard_in_the_images_layout() {
    let manifest = read("deploy/k8s/eval-run-job.yaml");
    let job = manifest.split("\n---").find(|d| d.contains("kind: Job")).expect("a Job");
    assert_eq!(field(job, "completionMode"), "Indexed");
    let completions = field(job, "completions");
    assert_eq!(field(job, "parallelism"), completions);
    // `--shard auto` reads the count from JOB_COMPLETIONS, which Kubernetes does not set.
    let env_at = job.find("name: JOB_COMPLETIONS").expect("JOB_COMPLETIONS set");
    assert_eq!(field(&job[env_at..], "value"), completions, "JOB_COMPLETIONS is the Job's completions");
    if job.contains("backoffLimitPerIndex") {
        assert_eq!(field(job, "restartPolicy"), "Never", "Kubernetes refuses backoffLimitPerIndex otherwise");
    }
    assert_eq!(field(job, "image"), "marvin:latest", "the Dockerfile's image (`docker build -t marvin .`)");
    assert!(read("Dockerfile").contains("-t marvin ."), "the Dockerfile says how to tag its image");

    // The container's shell command (the folded `args` block), with the scene count cut to one
    // scene per shard, on tuning seeds of the ideal world (whose calibration the fixtures hold),
    // and /results a scratch folder holding that calibration.
    let folded = job.split("- >-\n").nth(1).expect("args as a folded block");
    let command: Vec<&str> = folded.lines().take_while(|l| l.starts_with("              ")).map(str::trim).collect();
    let command = command.join(" ");
    let scenes: u64 = command.split("--scenes ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert_eq!(scenes % completions.parse::<u64>().unwrap(), 0, "every shard runs as many scenes");
    let dir = scratch("indexed_job");
    let workdir = image_layout(&dir.join("image"));
    let results = dir.join("results");
    std::fs::create_dir_all(results.join("cell")).unwrap();
    for f in ["cameras.json", "hand_eye.json"] {
        std::fs::copy(format!("{FIXTURES}/{f}"), results.join("cell").join(f)).unwrap();
    }
    let first: u64 = command.split("--seed ").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    let world = command.split("eval run ").nth(1).unwrap().split(' ').next().unwrap();
    assert!(workdir.join(world).is_file(), "the image holds the Job's world {world}");
    let command = command
        .replace(&format!("--scenes {scenes}"), &format!("--scenes {completions}"))
        .replace(&format!("--seed {first}"), "--seed 1")
        .replace(world, "worlds/ideal/widgets.toml")
        .replace("/results", &results.display().to_string())
        .replace("exec marvin ", &format!("exec {} ", env!("CARGO_BIN_EXE_marvin")));
    let o = Command::new("/bin/sh")
        .args(["-c", &command])
        .current_dir(&workdir)
        .envs(image_env(&dir.join("image")))
        .env("JOB_COMPLETION_INDEX", "3")
        .env("JOB_COMPLETIONS", completions)
        .output()
        .unwrap();
    assert!(o.status.success(), "{command}: {}", String::from_utf8_lossy(&o.stderr));
    let report: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["shard"], format!("4/{completions}"));
    let record = std::fs::read_to_string(results.join("shard-3.jsonl")).expect("pod 3's records");
    let record: serde_json::Value = serde_json::from_str(record.lines().next().unwrap()).unwrap();
    assert_eq!(record["seed"], 4, "pod 3 ran the fourth scene");
}
