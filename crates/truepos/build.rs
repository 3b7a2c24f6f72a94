//! Build script: records the git commit the binary was built from (`TRUEPOS_BUILD_COMMIT`, for
//! the report's document control and `--version`), or `unknown` outside a git checkout (a crate
//! tarball). Never fails the build.

use std::process::Command;

fn main() {
    let commit = Command::new("git")
        .args(["rev-parse", "--short=12", "HEAD"])
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok())
        .map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_hexdigit()))
        .unwrap_or_else(|| "unknown".to_string());
    println!("cargo:rustc-env=TRUEPOS_BUILD_COMMIT={commit}");
    // Rebuild when HEAD moves (the path is relative to this crate; absent outside git: ignored).
    println!("cargo:rerun-if-changed=../../.git/HEAD");
    println!("cargo:rerun-if-changed=../../.git/refs/heads");
    println!("cargo:rerun-if-changed=build.rs");
}
