//! Stamps the binary with the commit it was built from (`MARVIN_COMMIT`), so per-scene results
//! say which code made them and `marvin eval merge` refuses to mix versions. Outside a git
//! checkout (a container built from a tarball) the commit is `unknown`.

fn main() {
    let commit = std::process::Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=MARVIN_COMMIT={commit}");
    println!("cargo:rerun-if-changed=.git/HEAD");
    println!("cargo:rerun-if-changed=.git/refs/heads");
    println!("cargo:rerun-if-env-changed=MARVIN_COMMIT");
}
