//! Stamps the binary with the commit it was built from (`MARVIN_COMMIT`), so per-scene results
//! say which code made them and `marvin eval merge` refuses to mix versions: the environment's
//! `MARVIN_COMMIT` if set (the `Dockerfile` passes it as a build argument, as the image is built
//! without `.git`), else the checkout's commit, else `unknown`.

fn main() {
    let given = std::env::var("MARVIN_COMMIT").ok().filter(|c| !c.is_empty());
    let commit = given.or_else(from_git).unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=MARVIN_COMMIT={commit}");
    println!("cargo:rerun-if-changed=.git/HEAD");
    println!("cargo:rerun-if-changed=.git/refs/heads");
    println!("cargo:rerun-if-env-changed=MARVIN_COMMIT");
}

/// The checkout's commit, if this is a git checkout.
fn from_git() -> Option<String> {
    std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
}
