//! The first command line: convert a fixture, verify good and broken files, exit codes.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bvhc(args: &[&Path]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_bvhc")).args(args).output().expect("bvhc runs")
}

fn fixture(relative: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(relative)
}

#[test]
fn converting_the_fixture_writes_a_file_that_verifies() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("teapot.bvh");
    let run = bvhc(&[&fixture("fixtures/scenes/teapot.obj"), Path::new("-o"), &output]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(String::from_utf8_lossy(&run.stdout).contains("6320 triangles"));
    let verify = bvhc(&[Path::new("verify"), &output]);
    assert_eq!(verify.status.code(), Some(0));
    let file = bvhc::loader::BvhFile::read(&output).unwrap();
    let metadata = file.view().metadata_str().unwrap().unwrap().to_string();
    assert!(metadata.contains("\"file_name\":\"teapot.obj\"") && !metadata.contains(env!("CARGO_MANIFEST_DIR")));
}

#[test]
fn verify_names_the_broken_rule_and_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.bvh");
    let mut bytes = std::fs::read(fixture("fixtures/golden/quad-v1.0.bvh")).unwrap();
    let last = bytes.len() - 2;
    bytes[last] ^= 0x20;
    std::fs::write(&path, bytes).unwrap();
    let run = bvhc(&[Path::new("verify"), &path]);
    assert_eq!(run.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&run.stderr).contains("V12"), "{}", String::from_utf8_lossy(&run.stderr));
}

#[test]
fn a_missing_input_exits_1_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.bvh");
    let run = bvhc(&[&dir.path().join("missing.obj"), Path::new("-o"), &output]);
    assert_eq!(run.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&run.stderr).contains("missing.obj"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn bad_usage_exits_2() {
    assert_eq!(bvhc(&[Path::new("--frobnicate")]).status.code(), Some(2));
}
