//! The Python package's own tests (`crates/bvhc-py/tests`, pytest), run with the virtual environment that
//! `scripts/python-package.sh` installs the built wheel into, exactly as a user installs it: hits equal to
//! `bvhc trace`'s records (this build's `bvhc`), arrays built as their PLY converts, every error path, no leak.

use std::path::Path;
use std::process::Command;

use crate::skips::{Needs, skipped};

#[test]
fn the_installed_python_package_passes_its_tests() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let python = root.join("target/python/venv/bin/python");
    if !python.is_file() {
        skipped(
            Needs::Python,
            "the Python package's tests (scripts/python-package.sh installs it into target/python/venv)",
        );
        return;
    }
    let mut command = Command::new(&python);
    command
        .args(["-m", "pytest", "-q", "-rs", "-p", "no:cacheprovider", "crates/bvhc-py/tests"])
        .current_dir(root)
        .env("BVHC_BIN", env!("CARGO_BIN_EXE_bvhc"));
    if let Some(scenes) = crate::common::scenes_dir() {
        command.env("BVHC_SCENES", scenes);
    }
    let run = command.output().expect("the virtual environment's Python runs");
    let out = format!("{}{}", String::from_utf8_lossy(&run.stdout), String::from_utf8_lossy(&run.stderr));
    assert!(run.status.success(), "pytest failed:\n{out}");
    // Each test pytest skipped is reported as this suite's skips are, by what it lacked (`-rs` lists the reasons).
    for reason in out.lines().filter(|l| l.starts_with("SKIPPED")) {
        let needs = if reason.contains("dask") {
            Needs::Dask
        } else if reason.contains("scene") {
            Needs::Scenes
        } else {
            Needs::Machine
        };
        skipped(needs, format!("part of the Python package's tests: {reason}"));
    }
}
