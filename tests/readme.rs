//! The README as a newcomer meets it: short, its two commands true, every link resolving inside
//! the repository, and its layout table matching the tree.

use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> String {
    std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The most lines the README may have: what a newcomer reads before starting.
const MAX_README_LINES: usize = 250;

#[test]
fn the_readme_is_short() {
    let n = read(&root().join("README.md")).lines().count();
    assert!(n <= MAX_README_LINES, "README.md has {n} lines; at most {MAX_README_LINES} (move detail into docs/)");
}

/// The first code block: the main job on a shipped world, and the test command CI runs.
#[test]
fn the_readme_opens_with_the_two_commands() {
    let readme = read(&root().join("README.md"));
    let block: Vec<&str> =
        readme.split("```").nth(1).expect("a code block").lines().skip(1).filter(|l| !l.trim().is_empty()).collect();
    assert_eq!(block.len(), 2, "two commands: {block:?}");
    let command = |l: &str| l.split('#').next().unwrap().trim().to_string();
    let run = command(block[0]);
    let world = run.strip_prefix("cargo run --release -- run ").expect("the main job first").split(' ').next().unwrap();
    assert!(root().join(world).is_file(), "the main job's world {world} exists");
    let test = command(block[1]);
    let ci = read(&root().join(".ci/run"));
    assert!(ci.lines().any(|l| l.trim().starts_with(&test)), "CI runs the README's test command `{test}`");
}

/// Every `[text](target)` of a markdown text: its targets.
fn links(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find("](") {
        let tail = &rest[at + 2..];
        let end = tail.find(')').unwrap_or(tail.len());
        out.push(tail[..end].to_string());
        rest = &tail[end..];
    }
    out
}

/// GitHub's anchor for a heading: lower case, spaces to dashes, other punctuation dropped.
fn anchor(heading: &str) -> String {
    heading
        .trim_start_matches('#')
        .trim()
        .to_lowercase()
        .chars()
        .filter_map(|c| match c {
            ' ' => Some('-'),
            c if c.is_alphanumeric() || c == '-' || c == '_' => Some(c),
            _ => None,
        })
        .collect()
}

/// Where each link of `file` fails to resolve inside the repository (web links are not ours).
fn broken_links(file: &Path) -> Vec<String> {
    let dir = file.parent().unwrap();
    let mut broken = Vec::new();
    for target in links(&read(file)) {
        if target.starts_with("http://") || target.starts_with("https://") {
            continue;
        }
        let (path, fragment) = target.split_once('#').unwrap_or((&target, ""));
        let resolved = if path.is_empty() { file.to_path_buf() } else { dir.join(path) };
        let inside = resolved.canonicalize().is_ok_and(|p| p.starts_with(root().canonicalize().unwrap()));
        if !inside {
            broken.push(format!("{}: `{target}` is not a file of the repository", file.display()));
            continue;
        }
        if !fragment.is_empty() && resolved.is_file() {
            let headings: Vec<String> = read(&resolved).lines().filter(|l| l.starts_with('#')).map(anchor).collect();
            if !headings.iter().any(|h| h == fragment) {
                broken.push(format!("{}: `{target}`: no heading #{fragment}", file.display()));
            }
        }
    }
    broken
}

#[test]
fn every_link_of_the_readme_and_docs_resolves_inside_the_repository() {
    let mut files = vec![root().join("README.md")];
    for entry in std::fs::read_dir(root().join("docs")).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "md") {
            files.push(p);
        }
    }
    let broken: Vec<String> = files.iter().flat_map(|f| broken_links(f)).collect();
    assert!(broken.is_empty(), "{broken:#?}");
}

#[test]
fn the_link_checker_finds_what_is_broken() {
    assert_eq!(links("see [a](docs/A.md) and [b](B.md#x-y)"), ["docs/A.md", "B.md#x-y"]);
    assert_eq!(anchor("## Which seeds were used for what"), "which-seeds-were-used-for-what");
    assert_eq!(anchor("### Frames, and units"), "frames-and-units");
    let dir = std::env::temp_dir().join(format!("readme-links-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("x.md");
    std::fs::write(&f, "[a](nowhere.md)").unwrap();
    assert_eq!(broken_links(&f).len(), 1, "a file outside the repository, and missing");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The first column's paths of the README's layout table.
fn layout_paths(readme: &str) -> Vec<String> {
    let table = readme.split("## Layout").nth(1).expect("a Layout section");
    table
        .lines()
        .take_while(|l| !l.starts_with("## "))
        .filter(|l| l.starts_with("| `"))
        .flat_map(|l| {
            let first = l.split(" | ").next().unwrap();
            first.split('`').skip(1).step_by(2).map(str::to_string).collect::<Vec<_>>()
        })
        .collect()
}

/// The repository's files as git tracks them (a checkout's own scratch, ignored or untracked,
/// is not the repository's), or, outside a git checkout, the files on the disk.
fn tracked_files() -> Vec<PathBuf> {
    let git = std::process::Command::new("git").args(["ls-files"]).current_dir(root()).output();
    match git {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout).lines().map(PathBuf::from).collect(),
        _ => {
            let mut files = Vec::new();
            for entry in std::fs::read_dir(root()).unwrap() {
                let path = entry.unwrap().path();
                files.push(path.strip_prefix(root()).unwrap().join("-"));
            }
            for entry in std::fs::read_dir(root().join("src")).unwrap() {
                files.push(Path::new("src").join(entry.unwrap().file_name()).join("-"));
            }
            files
        }
    }
}

/// What a newcomer would look for in the table: the repository's top-level folders and files,
/// and every file and folder of `src/`.
fn entries_to_name() -> Vec<String> {
    let skip = ["target", ".git", ".gitignore", "Cargo.toml", "Cargo.lock", "README.md", "rustfmt.toml"];
    let mut out: Vec<String> = Vec::new();
    for f in tracked_files() {
        let parts: Vec<String> = f.iter().map(|p| p.to_string_lossy().into_owned()).collect();
        let entry = match parts.as_slice() {
            [src, inner, ..] if src == "src" => format!("src/{inner}"),
            [first, ..] => first.clone(),
            [] => continue,
        };
        if !skip.contains(&entry.as_str()) {
            out.push(entry);
        }
    }
    out.sort();
    out.dedup();
    out
}

#[test]
fn the_layout_table_matches_the_tree() {
    let named = layout_paths(&read(&root().join("README.md")));
    let missing: Vec<String> =
        named.iter().filter(|p| !root().join(p.trim_end_matches('/')).exists()).cloned().collect();
    assert!(missing.is_empty(), "the layout table names what is not there: {missing:?}");
    let trimmed: Vec<PathBuf> = named.iter().map(|p| PathBuf::from(p.trim_end_matches('/'))).collect();
    // A folder is named by itself or by a path inside it (`.ci/run`, `src/engine/`).
    let unnamed: Vec<String> =
        entries_to_name().into_iter().filter(|e| !trimmed.iter().any(|p| p.starts_with(e))).collect();
    assert!(unnamed.is_empty(), "the layout table misses: {unnamed:?}");
}
