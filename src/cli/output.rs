//! What every verb prints through.

use std::io::Write;

/// Prints a line to stdout; a reader that went away early (`marvin ... | head`) is no error.
pub fn emit(line: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{line}").and_then(|()| out.flush()) {
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
        other => Ok(other?),
    }
}

/// Settles a seeded scene of `scn`, warning on stderr when it did not come to rest (the scene is
/// used anyway: evaluations count such scenes). Returns the scene and whether it settled.
pub fn settle(scn: &sim::Scenario, seed: u64) -> (sim::Scene, bool) {
    let scene = sim::Scene::settle(scn, seed);
    let why = scene.unsettled();
    if let Some(why) = &why {
        eprintln!("warning: an unsettled scene, {why}");
    }
    (scene, why.is_none())
}

/// Progress of a long evaluation on stderr: a bar on a terminal (indicatif), with a line per
/// step above it; without a terminal the lines alone; under `--json` nothing.
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    quiet: bool,
}

impl Progress {
    pub fn new(len: u64, json: bool) -> Progress {
        let terminal = std::io::IsTerminal::is_terminal(&std::io::stderr());
        let bar = (terminal && !json).then(|| {
            let bar = indicatif::ProgressBar::new(len);
            if let Ok(style) = indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} [{elapsed} < {eta}]") {
                bar.set_style(style);
            }
            bar
        });
        Progress { bar, quiet: json }
    }

    /// A line about the step just done, and the bar moved on.
    pub fn step(&self, line: String) {
        match &self.bar {
            Some(bar) => {
                bar.println(line);
                bar.inc(1);
            }
            None if !self.quiet => eprintln!("{line}"),
            None => {}
        }
    }

    pub fn finish(self) {
        if let Some(bar) = self.bar {
            bar.finish_and_clear();
        }
    }
}

/// Table 1's rows beside the paper's, under `heading`, with the speed-up and the slices'
/// parallel efficiency.
pub fn table1(heading: &str, rows: &[marvin::engine::run::Table1Row], efficiency: f64) -> anyhow::Result<()> {
    emit(heading)?;
    for r in rows {
        emit(&format!("  {:<15} {:>9.1}   paper {:>6.0}", r.stage, r.measured_ms, r.paper_ms))?;
    }
    let total = rows.last().map_or(f64::NAN, |r| r.measured_ms);
    emit(&format!(
        "  speed-up over the transputers {:.0}x; the slices' parallel efficiency {:.0}% (paper: over 80%)",
        10_000.0 / total,
        efficiency * 100.0
    ))
}
