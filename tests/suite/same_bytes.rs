//! Conversions keep their bytes: every row of `fixtures/same-bytes.tsv` (a scene, the command line's options,
//! the XXH3-64 of the file written) is converted again and must give exactly that file. The table holds every
//! shared scene with every preset and a set of option combinations over a few scenes; it changes only with a
//! change that is meant to change trees or files, and then in the same commit. Rows that took more than
//! [`QUICK_SECONDS`] when recorded run only with `BVHC_SAME_BYTES=all` (about four minutes more on 2 cores).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use xxhash_rust::xxh3::xxh3_64;

use crate::common::scenes_dir;

/// Rows recorded as taking longer than this (seconds on 2 cores) run only with `BVHC_SAME_BYTES=all`.
const QUICK_SECONDS: f64 = 1.0;

/// One row: the input (repository-relative under `fixtures/`, else relative to the shared scenes), the options,
/// the expected hash (or `exitN` for an input that is refused with exit code N), and the recorded seconds.
struct Row {
    input: String,
    options: Vec<String>,
    expected: String,
    seconds: f64,
}

fn rows() -> Vec<Row> {
    let table = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/same-bytes.tsv"))
        .expect("fixtures/same-bytes.tsv is readable");
    table
        .lines()
        .filter(|line| !line.is_empty() && !line.starts_with('#'))
        .map(|line| {
            let fields: Vec<&str> = line.split('\t').collect();
            let (input, options, expected, seconds) = match fields[..] {
                [input, options, expected] => (input, options, expected, 0.0),
                [input, options, expected, seconds] => (input, options, expected, seconds.parse().unwrap()),
                _ => panic!("malformed row: {line}"),
            };
            Row {
                input: input.to_string(),
                options: options.split_whitespace().map(String::from).collect(),
                expected: expected.to_string(),
                seconds,
            }
        })
        .collect()
}

fn input_path(input: &str) -> Option<PathBuf> {
    if input.starts_with("fixtures/") {
        return Some(Path::new(env!("CARGO_MANIFEST_DIR")).join(input));
    }
    scenes_dir().map(|dir| dir.join(input)).filter(|path| path.is_file())
}

/// What converting `input` with `options` gives: the written file's hash, or the exit code.
fn outcome(input: &Path, options: &[String], output: &Path) -> String {
    let status = Command::new(env!("CARGO_BIN_EXE_bvhc"))
        .arg(input)
        .arg("-o")
        .arg(output)
        .args(["--force", "--quiet"])
        .args(options)
        .stderr(Stdio::null())
        .status()
        .expect("bvhc runs");
    match status.code() {
        Some(0) => format!("{:016x}", xxh3_64(&std::fs::read(output).expect("the output is readable"))),
        code => format!("exit{}", code.unwrap_or(-1)),
    }
}

#[test]
fn every_recorded_conversion_writes_the_recorded_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.bvh");
    let all = std::env::var("BVHC_SAME_BYTES").is_ok_and(|v| v == "all");
    let (mut checked, mut skipped, mut slow, mut differing) = (0, 0, 0, Vec::new());
    for row in rows() {
        if !all && row.seconds > QUICK_SECONDS {
            slow += 1;
            continue;
        }
        let Some(input) = input_path(&row.input) else {
            skipped += 1;
            continue;
        };
        let got = outcome(&input, &row.options, &output);
        if got != row.expected {
            differing.push(format!("{} {}: {} (recorded {})", row.input, row.options.join(" "), got, row.expected));
        }
        checked += 1;
    }
    if slow > 0 {
        crate::skips::skipped(
            crate::skips::Needs::Slow,
            format!(
                "part: {slow} same-bytes rows that took over {QUICK_SECONDS} s when recorded (BVHC_SAME_BYTES=all runs them)"
            ),
        );
    }
    if skipped > 0 {
        crate::skips::skipped(
            crate::skips::Needs::Scenes,
            format!("part: {skipped} same-bytes rows whose scene is missing"),
        );
    }
    assert!(differing.is_empty(), "{} of {checked} conversions changed:\n{}", differing.len(), differing.join("\n"));
}
