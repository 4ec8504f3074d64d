//! Scene batches at scale: a seed range cut into shards, one JSON line per scene written as it
//! ends, a batch resumed from its file, and files merged into the summary one process prints.
//!
//! - [`Shard`]: shard K of N runs the scenes whose index in the range (0-based) leaves K - 1
//!   when divided by N: round robin, so shards of a range whose scenes differ in cost stay
//!   alike. `auto` reads the scheduler's index (Slurm job arrays, Kubernetes Indexed Jobs).
//! - [`Record`]: what one scene gave, with the verb, world, seed range and code version.
//! - [`RecordFile`]: appends records, flushed scene by scene, so a killed job loses at most the
//!   scene it was on; [`read_records`] reads them back, naming the line at fault.
//! - [`check_batch`]: that a set of records is one batch, whole: one verb, world, range and
//!   version, every seed once.

use anyhow::{Context, bail};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The code version a record carries: the package version and the commit it was built from.
pub fn code_version() -> String {
    format!("{} ({})", env!("CARGO_PKG_VERSION"), env!("MARVIN_COMMIT"))
}

/// One shard of a seed range: `index` counts from 0, up to `count - 1`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl Shard {
    /// The whole range.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// `K/N` (K from 1 to N), or `auto` (the scheduler's index, from `env`).
    pub fn parse(text: &str, env: &dyn Fn(&str) -> Option<String>) -> anyhow::Result<Shard> {
        if text == "auto" {
            return Shard::from_scheduler(env);
        }
        let (k, n) =
            text.split_once('/').with_context(|| format!("--shard {text}: give K/N (shard K of N) or auto"))?;
        let (k, n): (u64, u64) = (
            k.trim().parse().with_context(|| format!("--shard {text}: K is not a whole number"))?,
            n.trim().parse().with_context(|| format!("--shard {text}: N is not a whole number"))?,
        );
        if n == 0 || k == 0 || k > n {
            bail!("--shard {text}: K must be 1 to N, and N at least 1");
        }
        Ok(Shard { index: k - 1, count: n })
    }

    /// The shard a scheduler gave this task: a Slurm job array (`SLURM_ARRAY_TASK_ID` less
    /// `SLURM_ARRAY_TASK_MIN`, of `SLURM_ARRAY_TASK_COUNT`), or a Kubernetes Indexed Job
    /// (`JOB_COMPLETION_INDEX`, of `JOB_COMPLETIONS`, which the job's manifest sets to its
    /// `completions`: Kubernetes does not say it).
    pub fn from_scheduler(env: &dyn Fn(&str) -> Option<String>) -> anyhow::Result<Shard> {
        let number = |name: &str| -> anyhow::Result<Option<u64>> {
            env(name)
                .map(|v| v.trim().parse::<u64>().with_context(|| format!("{name}={v:?} is not a whole number")))
                .transpose()
        };
        let (index, count) = if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
            let min = number("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
            let count = number("SLURM_ARRAY_TASK_COUNT")?
                .context("SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not")?;
            (id.checked_sub(min).context("SLURM_ARRAY_TASK_ID is below SLURM_ARRAY_TASK_MIN")?, count)
        } else if let Some(index) = number("JOB_COMPLETION_INDEX")? {
            let count = number("JOB_COMPLETIONS")?.context(
                "JOB_COMPLETION_INDEX is set but JOB_COMPLETIONS is not: set it in the Job's env to its completions",
            )?;
            (index, count)
        } else {
            bail!(
                "--shard auto: no scheduler's index here (neither SLURM_ARRAY_TASK_ID nor JOB_COMPLETION_INDEX is set); give --shard K/N"
            );
        };
        if count == 0 || index >= count {
            bail!(
                "--shard auto: task {index} of {count} is no shard (an array of N tasks must be 0..N-1 above its first)"
            );
        }
        Ok(Shard { index, count })
    }

    /// The seeds of this shard, of the `scenes` from `first`.
    pub fn seeds(&self, first: u64, scenes: u64) -> Vec<u64> {
        (0..scenes).filter(|i| i % self.count == self.index).map(|i| first + i).collect()
    }
}

/// What one scene gave, as one line of a `--out` file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// `run`, `locate`, `pick`, ...
    pub verb: String,
    /// The world file as given.
    pub world: String,
    /// The whole batch's seeds, first and last (every shard's records carry the same).
    pub range: [u64; 2],
    pub version: String,
    pub seed: u64,
    /// What the batch shares (a calibration made once), the same in every record.
    pub shared: serde_json::Value,
    /// The scene's own figures and failures.
    pub scene: serde_json::Value,
}

/// A `--out` file records are appended to.
pub struct RecordFile {
    path: PathBuf,
    file: std::fs::File,
}

impl RecordFile {
    /// Opens `path` to append to (made if missing).
    pub fn append(path: &Path) -> anyhow::Result<RecordFile> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("making {}", dir.display()))?;
        }
        let file = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .with_context(|| format!("opening {} to append to", path.display()))?;
        Ok(RecordFile { path: path.to_path_buf(), file })
    }

    /// Appends one record as a line and flushes it to the disk.
    pub fn write(&mut self, record: &Record) -> anyhow::Result<()> {
        let line = serde_json::to_string(record)?;
        writeln!(self.file, "{line}")
            .and_then(|_| self.file.sync_data())
            .with_context(|| format!("writing {}", self.path.display()))
    }
}

/// The records of a `--out` file, naming the line at fault. A last line cut short (a job killed
/// while writing it) is left out, as if that scene had not ended.
pub fn read_records(path: &Path) -> anyhow::Result<Vec<Record>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    for (k, line) in lines.iter().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        match serde_json::from_str::<Record>(line) {
            Ok(r) => out.push(r),
            Err(_) if k + 1 == lines.len() && !text.ends_with('\n') => {}
            Err(e) => bail!("{}:{}: not a scene record: {e}", path.display(), k + 1),
        }
    }
    Ok(out)
}

/// That `records` are one whole batch: one verb, world, range and version, and every seed of the
/// range exactly once. Returns them by seed.
pub fn check_batch(records: Vec<Record>) -> anyhow::Result<Vec<Record>> {
    let Some(first) = records.first().cloned() else { bail!("no scene records") };
    for (what, differs) in [
        ("verbs", records.iter().any(|r| r.verb != first.verb)),
        ("worlds", records.iter().any(|r| r.world != first.world)),
        ("seed ranges", records.iter().any(|r| r.range != first.range)),
        ("code versions", records.iter().any(|r| r.version != first.version)),
        ("shared calibrations", records.iter().any(|r| r.shared != first.shared)),
    ] {
        if differs {
            let mut seen: Vec<String> = records
                .iter()
                .map(|r| match what {
                    "verbs" => r.verb.clone(),
                    "worlds" => r.world.clone(),
                    "seed ranges" => format!("{:?}", r.range),
                    "code versions" => r.version.clone(),
                    _ => r.shared.to_string(),
                })
                .collect();
            seen.sort();
            seen.dedup();
            bail!("the records are of different {what}: {}", seen.join(", "));
        }
    }
    let mut by_seed: BTreeMap<u64, Vec<Record>> = BTreeMap::new();
    for r in records {
        by_seed.entry(r.seed).or_default().push(r);
    }
    let [lo, hi] = first.range;
    let missing: Vec<u64> = (lo..=hi).filter(|s| !by_seed.contains_key(s)).collect();
    let twice: Vec<u64> = by_seed.iter().filter(|(_, v)| v.len() > 1).map(|(s, _)| *s).collect();
    let outside: Vec<u64> = by_seed.keys().copied().filter(|s| !(lo..=hi).contains(s)).collect();
    if !missing.is_empty() || !twice.is_empty() || !outside.is_empty() {
        bail!(
            "the batch {lo}-{hi} is not whole: {} seeds missing {}, {} more than once {}, {} outside it {}",
            missing.len(),
            seeds_text(&missing),
            twice.len(),
            seeds_text(&twice),
            outside.len(),
            seeds_text(&outside)
        );
    }
    Ok(by_seed.into_values().map(|mut v| v.remove(0)).collect())
}

/// Seeds as ranges: `[3, 5-9]`.
fn seeds_text(seeds: &[u64]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < seeds.len() {
        let mut j = i;
        while j + 1 < seeds.len() && seeds[j + 1] == seeds[j] + 1 {
            j += 1;
        }
        parts.push(if i == j { seeds[i].to_string() } else { format!("{}-{}", seeds[i], seeds[j]) });
        i = j + 1;
    }
    format!("[{}]", parts.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let map: BTreeMap<String, String> = pairs.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
        move |k| map.get(k).cloned()
    }

    #[test]
    fn shards_partition_the_range_round_robin() {
        let none = env(&[]);
        let shards: Vec<Shard> = (1..=4).map(|k| Shard::parse(&format!("{k}/4"), &none).unwrap()).collect();
        let mut all: Vec<u64> = shards.iter().flat_map(|s| s.seeds(100, 10)).collect();
        assert_eq!(shards[1].seeds(100, 10), [101, 105, 109]);
        all.sort();
        assert_eq!(all, (100..110).collect::<Vec<_>>());
        assert_eq!(Shard::ALL.seeds(5, 3), [5, 6, 7]);
        for bad in ["0/4", "5/4", "1/0", "x/4", "4", ""] {
            assert!(Shard::parse(bad, &none).is_err(), "{bad}");
        }
    }

    #[test]
    fn auto_reads_slurm_and_kubernetes_and_refuses_without_either() {
        let slurm =
            env(&[("SLURM_ARRAY_TASK_ID", "7"), ("SLURM_ARRAY_TASK_MIN", "5"), ("SLURM_ARRAY_TASK_COUNT", "4")]);
        assert_eq!(Shard::parse("auto", &slurm).unwrap(), Shard { index: 2, count: 4 });
        let k8s = env(&[("JOB_COMPLETION_INDEX", "3"), ("JOB_COMPLETIONS", "4")]);
        assert_eq!(Shard::parse("auto", &k8s).unwrap(), Shard { index: 3, count: 4 });
        let e = Shard::parse("auto", &env(&[])).unwrap_err().to_string();
        assert!(e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"), "{e}");
        let e = Shard::parse("auto", &env(&[("JOB_COMPLETION_INDEX", "0")])).unwrap_err().to_string();
        assert!(e.contains("JOB_COMPLETIONS"), "{e}");
        assert!(Shard::parse("auto", &env(&[("JOB_COMPLETION_INDEX", "4"), ("JOB_COMPLETIONS", "4")])).is_err());
    }

    fn record(seed: u64) -> Record {
        Record {
            verb: "run".into(),
            world: "w.toml".into(),
            range: [10, 13],
            version: code_version(),
            seed,
            shared: serde_json::json!({}),
            scene: serde_json::json!({ "x": seed }),
        }
    }

    #[test]
    fn a_batch_must_be_whole_and_of_one_kind() {
        let whole: Vec<Record> = [13, 11, 10, 12].map(record).into();
        assert_eq!(check_batch(whole).unwrap().iter().map(|r| r.seed).collect::<Vec<_>>(), [10, 11, 12, 13]);
        let e = check_batch([10, 11, 11].map(record).into()).unwrap_err().to_string();
        assert!(e.contains("missing [12-13]") && e.contains("more than once [11]"), "{e}");
        let mut other = record(12);
        other.version = "0.0.0 (old)".into();
        let e = check_batch(vec![record(10), record(11), other, record(13)]).unwrap_err().to_string();
        assert!(e.contains("code versions"), "{e}");
        let mut other = record(12);
        other.world = "x.toml".into();
        assert!(
            check_batch(vec![record(10), record(11), other, record(13)]).unwrap_err().to_string().contains("worlds")
        );
    }

    #[test]
    fn records_round_trip_and_a_cut_last_line_is_left_out() {
        let dir = std::env::temp_dir().join(format!("batch-records-{}", std::process::id()));
        let path = dir.join("out.jsonl");
        let _ = std::fs::remove_dir_all(&dir);
        let mut f = RecordFile::append(&path).unwrap();
        f.write(&record(10)).unwrap();
        f.write(&record(11)).unwrap();
        drop(f);
        let mut text = std::fs::read_to_string(&path).unwrap();
        text.push_str("{\"verb\":\"ru");
        std::fs::write(&path, &text).unwrap();
        assert_eq!(read_records(&path).unwrap(), vec![record(10), record(11)]);
        std::fs::write(&path, "{}\n").unwrap();
        let e = read_records(&path).unwrap_err().to_string();
        assert!(e.contains("out.jsonl:1"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
