//! Checks that cannot run here are reported, not hidden: [`skipped`] prints the skip at once past the test
//! harness's capture (libtest shows a passing test's output only with `--nocapture`), records it for the summary
//! that `tests/summary.rs` prints after the suite, and fails the test instead when `BVHC_REQUIRE` names what was
//! missing (`.ci/run` names what it installs itself, so a CI run cannot pass by skipping it).

use std::io::Write;

/// What a skipped check needed. `BVHC_REQUIRE` lists these names, comma-separated (`all` for every one).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Needs {
    /// The shared scenes (`../shared/scenes` or `BVHC_SCENES`).
    Scenes,
    /// A C compiler (`cc` or `CC`).
    CCompiler,
    /// A GPU adapter for wgpu (in CI, Mesa's lavapipe).
    Vulkan,
    /// Something the workspace builds beside the tests (the C library, the examples).
    Build,
    /// A system tool or device file (`mkfifo`, `prlimit`, `/dev/full`, `pkg-config`, `cmake`).
    Tools,
    /// A property of this machine (an instruction set, a file system's unnamed files, timing).
    Machine,
    /// Work left out by choice (`BVHC_SAME_BYTES=all` runs it).
    Slow,
    /// The Python package installed into `target/python/venv` (`scripts/python-package.sh`).
    Python,
    /// Pixar's USD Python bindings (`usd-core`) in `target/usd/venv` (`scripts/usd-core.sh`), the USD oracle.
    Usd,
    /// Dask's distributed scheduler in `target/python/venv` (`scripts/python-package.sh` installs it), for
    /// `convert_many` on a cluster.
    Dask,
}

impl Needs {
    /// The name `BVHC_REQUIRE` and the summary use.
    pub fn name(self) -> &'static str {
        match self {
            Needs::Scenes => "scenes",
            Needs::CCompiler => "c-compiler",
            Needs::Vulkan => "vulkan",
            Needs::Build => "build",
            Needs::Tools => "tools",
            Needs::Machine => "machine",
            Needs::Slow => "slow",
            Needs::Python => "python",
            Needs::Usd => "usd",
            Needs::Dask => "dask",
        }
    }

    /// Whether `BVHC_REQUIRE` makes a skip for want of this a failure.
    fn required(self) -> bool {
        std::env::var("BVHC_REQUIRE")
            .is_ok_and(|list| list.split(',').map(str::trim).any(|name| name == "all" || name == self.name()))
    }
}

/// The file the suite's skips are recorded in, one line each: process id, what was needed, what was skipped.
pub fn log_path() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("skipped-checks.tsv")
}

/// Reports that `what` (a check, or part of one) did not run for want of `needs`: printed at once, recorded for
/// the summary, and a panic when `BVHC_REQUIRE` requires it.
#[track_caller]
pub fn skipped(needs: Needs, what: impl std::fmt::Display) {
    let line = format!("SKIPPED ({}): {what}", needs.name());
    assert!(!needs.required(), "{line}, but BVHC_REQUIRE requires {}", needs.name());
    let _ = writeln!(std::io::stderr(), "{line}");
    let record = format!("{}\t{}\t{}\n", std::process::id(), needs.name(), what.to_string().replace(['\t', '\n'], " "));
    let file = std::fs::OpenOptions::new().create(true).append(true).open(log_path());
    if let Ok(mut file) = file {
        let _ = file.write_all(record.as_bytes());
    }
}
