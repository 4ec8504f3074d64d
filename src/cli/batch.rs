//! The scene loop the batched `eval` verbs share (`docs/SCALE.md`): the seeds of `--shard` not
//! yet in `--out`'s file, `--jobs` at a time, each recorded as it ends; and printing the summary
//! that `marvin eval merge` prints the same way from the records of every shard.

use super::output::{Progress, emit};
use anyhow::bail;
use marvin::eval::batch::{Record, RecordFile, Shard, code_version, read_records};
use serde_json::{Value, json};
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Instant;

/// A batch of seeded scenes, as the command line gives it.
pub struct Batch {
    pub world: PathBuf,
    pub scenes: u64,
    pub seed: u64,
    pub json: bool,
    pub shard: Shard,
    /// Where each scene's record is appended as it ends.
    pub out: Option<PathBuf>,
    /// Skip the scenes already in `out`.
    pub resume: bool,
    /// Scenes at once.
    pub jobs: usize,
}

impl Batch {
    /// The whole batch's first and last seed (every shard's).
    pub fn range(&self) -> [u64; 2] {
        [self.seed, self.seed + self.scenes - 1]
    }
}

/// One scene's outcome: its record's `scene`, and a line for the progress display.
pub type SceneOutcome = anyhow::Result<(Value, String)>;

/// A batch's records so far, and the file new ones go to.
pub struct Runner<'a> {
    batch: &'a Batch,
    verb: &'static str,
    file: Option<Mutex<RecordFile>>,
    done: Vec<Record>,
}

impl<'a> Runner<'a> {
    /// Opens `--out` (refused if it holds records and `--resume` was not asked for, as appending
    /// would record scenes twice) and reads what a resumed batch carries on from: records of this
    /// verb, world, range and code version.
    pub fn open(batch: &'a Batch, verb: &'static str) -> anyhow::Result<Runner<'a>> {
        let Some(path) = &batch.out else {
            if batch.resume {
                bail!("--resume needs --out FILE (the records to carry on from)");
            }
            return Ok(Runner { batch, verb, file: None, done: Vec::new() });
        };
        let holds_records = std::fs::metadata(path).is_ok_and(|m| m.len() > 0);
        if holds_records && !batch.resume {
            bail!(
                "{} holds scene records already: --resume to carry on from them, or give another file",
                path.display()
            );
        }
        let done = if holds_records { read_records(path)? } else { Vec::new() };
        let world = batch.world.display().to_string();
        if let Some(r) = done.iter().find(|r| r.verb != verb || r.world != world || r.range != batch.range()) {
            bail!(
                "{}: seed {} is of `eval {}` on {} over {:?}, not `eval {verb}` on {world} over {:?}",
                path.display(),
                r.seed,
                r.verb,
                r.world,
                r.range,
                batch.range()
            );
        }
        if let Some(r) = done.iter().find(|r| r.version != code_version()) {
            bail!("{}: seed {} was run by {}, this is {}", path.display(), r.seed, r.version, code_version());
        }
        let file = Some(Mutex::new(RecordFile::append(path)?));
        Ok(Runner { batch, verb, file, done })
    }

    /// Runs `scene` on every seed of the shard not yet recorded, `--jobs` at a time, recording
    /// each as it ends; all the shard's records (earlier ones too), by seed. Stops at the first
    /// scene that fails (the scenes recorded so far stay recorded).
    pub fn run(self, shared: &Value, scene: &(dyn Fn(u64) -> SceneOutcome + Sync)) -> anyhow::Result<Vec<Record>> {
        let Runner { batch: b, verb, file, done } = self;
        if let Some(r) = done.iter().find(|r| &r.shared != shared) {
            bail!("seed {} was run with {}; this run has {shared}", r.seed, r.shared);
        }
        let todo: Vec<u64> =
            b.shard.seeds(b.seed, b.scenes).into_iter().filter(|s| !done.iter().any(|r| r.seed == *s)).collect();
        let progress = Progress::new(todo.len() as u64, b.json);
        let finished = Mutex::new(done);
        let next = Mutex::new(todo.into_iter());
        let failed: Mutex<Option<anyhow::Error>> = Mutex::new(None);
        let worker = || {
            while let Some(s) = next.lock().unwrap_or_else(|e| e.into_inner()).next() {
                if failed.lock().unwrap_or_else(|e| e.into_inner()).is_some() {
                    return;
                }
                let clock = Instant::now();
                let outcome = scene(s).and_then(|(figures, line)| {
                    let record = Record {
                        verb: verb.into(),
                        world: b.world.display().to_string(),
                        range: b.range(),
                        version: code_version(),
                        seed: s,
                        shared: shared.clone(),
                        scene: figures,
                    };
                    if let Some(f) = file.as_ref() {
                        f.lock().unwrap_or_else(|e| e.into_inner()).write(&record)?;
                    }
                    progress.step(format!("seed {s}: {line} ({:.1} s)", clock.elapsed().as_secs_f64()));
                    finished.lock().unwrap_or_else(|e| e.into_inner()).push(record);
                    Ok(())
                });
                if let Err(e) = outcome {
                    failed.lock().unwrap_or_else(|e| e.into_inner()).get_or_insert(e.context(format!("seed {s}")));
                }
            }
        };
        std::thread::scope(|scope| {
            for _ in 0..b.jobs.max(1) {
                scope.spawn(worker);
            }
        });
        progress.finish();
        if let Some(e) = failed.into_inner().unwrap_or_else(|e| e.into_inner()) {
            return Err(e);
        }
        let mut records = finished.into_inner().unwrap_or_else(|e| e.into_inner());
        records.sort_by_key(|r| r.seed);
        Ok(records)
    }
}

/// Prints a summary as `--json` asks (one line) or pretty, labelled with its shard if it is one.
pub fn print_report(mut report: Value, shard: Shard, json: bool) -> anyhow::Result<()> {
    if shard != Shard::ALL {
        report["shard"] = json!(format!("{}/{}", shard.index + 1, shard.count));
    }
    if json { emit(&report.to_string()) } else { emit(&serde_json::to_string_pretty(&report)?) }
}
