//! The command line: every subcommand, every documented exit code, up-to-date detection, determinism across
//! thread counts, and no output file left behind by a failure.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub(crate) fn bvhc(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_bvhc")).args(args.iter().map(|a| a.as_ref())).output().expect("bvhc runs")
}

pub(crate) fn stdout(output: &Output) -> String {
    String::from_utf8_lossy(&output.stdout).into_owned()
}

pub(crate) fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

pub(crate) fn teapot() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj")
}

fn golden() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/quad-v1.0.bvh")
}

pub(crate) fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

#[test]
fn convert_then_up_to_date_then_force() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("teapot.bvh");
    let run = bvhc(&[&teapot(), &"-o", &output]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(stdout(&run).contains("6320 triangles"), "{}", stdout(&run));
    assert!(stderr(&run).is_empty(), "no progress display without a terminal: {}", stderr(&run));
    let first = std::fs::read(&output).unwrap();
    let again = bvhc(&[&teapot(), &"-o", &output]);
    assert_eq!(again.status.code(), Some(0));
    assert!(stdout(&again).contains("is up to date"), "{}", stdout(&again));
    let other_options = bvhc(&[&teapot(), &"-o", &output, &"--max-leaf-size", &"4"]);
    assert!(!stdout(&other_options).contains("up to date"), "changed options rebuild");
    let forced = bvhc(&[&teapot(), &"-o", &output, &"--force"]);
    assert!(!stdout(&forced).contains("up to date"));
    assert_eq!(std::fs::read(&output).unwrap(), first, "same input and options, same bytes");
    assert_eq!(files_in(dir.path()), ["teapot.bvh"]);
}

#[test]
fn a_changed_input_is_not_up_to_date() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("scene.obj");
    std::fs::copy(teapot(), &input).unwrap();
    let output = dir.path().join("scene.bvh");
    assert_eq!(bvhc(&[&input, &"-o", &output]).status.code(), Some(0));
    let mut text = std::fs::read_to_string(&input).unwrap();
    text.push_str("v 0 0 0\n");
    std::fs::write(&input, text).unwrap();
    let run = bvhc(&[&input, &"-o", &output]);
    assert!(!stdout(&run).contains("up to date"), "{}", stdout(&run));
}

#[test]
fn one_and_two_threads_write_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let (one, two) = (dir.path().join("one.bvh"), dir.path().join("two.bvh"));
    assert_eq!(bvhc(&[&teapot(), &"-o", &one, &"--threads", &"1", &"--preset", &"max-quality"]).status.code(), Some(0));
    assert_eq!(bvhc(&[&teapot(), &"-o", &two, &"--threads", &"2", &"--preset", &"max-quality"]).status.code(), Some(0));
    assert_eq!(std::fs::read(one).unwrap(), std::fs::read(two).unwrap());
}

#[test]
fn convert_json_report_and_options() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("t.bvh");
    let run = bvhc(&[
        &teapot(),
        &"-o",
        &output,
        &"--json",
        &"--no-ids",
        &"--no-merge",
        &"--builder",
        &"spatial-median",
        &"--selection",
        &"area",
        &"--preset",
        &"fast",
    ]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let report: serde_json::Value = serde_json::from_str(&stdout(&run)).expect("stdout is JSON");
    assert_eq!(report["up_to_date"], false);
    assert_eq!(report["report"]["triangle_count"], 6320);
    assert!(report["files_read"][0].as_str().unwrap().ends_with("teapot.obj"));
    let file = bvhc::loader::BvhFile::read(&output).unwrap();
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    assert_eq!(metadata["build"]["max_leaf_size"], 1, "--no-merge is recorded as one triangle per leaf");
    assert!(file.view().triangle_ids().is_none(), "--no-ids omits the id sections");
    assert!(file.view().nodes().iter().all(|n| !n.is_leaf() || n.count == 1), "--no-merge keeps single leaves");
    let quiet = bvhc(&[&teapot(), &"-o", &output, &"--quiet", &"--force"]);
    assert!(stdout(&quiet).is_empty() && quiet.status.success());
}

#[test]
fn verify_exit_codes() {
    let good = bvhc(&[&"verify", &golden()]);
    assert_eq!(good.status.code(), Some(0));
    assert!(stdout(&good).contains("valid .bvh 1.0"));
    let dir = tempfile::tempdir().unwrap();
    let broken = dir.path().join("broken.bvh");
    let mut bytes = std::fs::read(golden()).unwrap();
    let at = bytes.len() - 2;
    bytes[at] ^= 0x20;
    std::fs::write(&broken, bytes).unwrap();
    let run = bvhc(&[&"verify", &broken]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("V12"), "{}", stderr(&run));
    let missing = bvhc(&[&"verify", &dir.path().join("missing.bvh")]);
    assert_eq!(missing.status.code(), Some(3));
    assert!(stderr(&missing).contains("missing.bvh"));
    let not_bvh = bvhc(&[&"verify", &teapot()]);
    assert_eq!(not_bvh.status.code(), Some(1));
    assert!(stderr(&not_bvh).contains("V1"));
}

#[test]
fn info_text_and_json() {
    let text = bvhc(&[&"info", &golden()]);
    assert_eq!(text.status.code(), Some(0));
    assert!(stdout(&text).contains("2 triangles, 3 nodes, 2 leaves, depth 1"), "{}", stdout(&text));
    let json = bvhc(&[&"info", &golden(), &"--json"]);
    let info: serde_json::Value = serde_json::from_str(&stdout(&json)).unwrap();
    for key in [
        "triangle_count",
        "node_count",
        "leaf_count",
        "max_depth",
        "sah_cost",
        "inner_area_ratio",
        "leaf_area_ratio",
        "format_version",
    ] {
        assert!(!info[key].is_null(), "{key} missing");
    }
    assert_eq!(
        (info["triangle_count"].as_u64(), info["leaf_count"].as_u64(), info["max_depth"].as_u64()),
        (Some(2), Some(2), Some(1))
    );
    assert_eq!(info["format_version"], "1.0");
    assert_eq!(info["source_vertices"], false);
    assert_eq!(info["not_opaque_count"], serde_json::Value::Null);
    assert!(stdout(&text).contains("opacity: every triangle opaque (no triangle_flags section)"), "{}", stdout(&text));
    assert!(stdout(&text).contains("provenance: source ids, no source vertices"), "{}", stdout(&text));
    // The 1.2 golden file: hits can interpolate the source's attributes.
    let golden_1_2 = golden().with_file_name("quad-v1.2.bvh");
    let text = stdout(&bvhc(&[&"info", &golden_1_2]));
    assert!(text.contains("provenance: source ids and source vertices"), "{text}");
    let info: serde_json::Value = serde_json::from_str(&stdout(&bvhc(&[&"info", &golden_1_2, &"--json"]))).unwrap();
    assert_eq!((info["format_version"].as_str(), info["source_vertices"].as_bool()), (Some("1.2"), Some(true)));
    assert_eq!(bvhc(&[&"info", &teapot()]).status.code(), Some(1));
}

#[test]
fn render_writes_a_png_of_the_requested_size() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("t.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &scene, &"--preset", &"fast"]).status.success());
    for heatmap in [false, true] {
        let image = dir.path().join(format!("t{heatmap}.png"));
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> =
            vec![&"render", &scene, &"-o", &image, &"--width", &"64", &"--height", &"48"];
        if heatmap {
            args.push(&"--heatmap");
        }
        let run = bvhc(&args);
        assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
        let png = std::fs::read(&image).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        let (width, height) =
            (u32::from_be_bytes(png[16..20].try_into().unwrap()), u32::from_be_bytes(png[20..24].try_into().unwrap()));
        assert_eq!((width, height), (64, 48));
    }
    // Every invalid --camera is a usage error (exit 2), found before the file is read.
    for camera in ["1,2,3", "nan,0,0,1,1,1", "0,0,0,0,0,0", "1,2,3,4,5,inf", "a,b,c,d,e,f", "1,2,3,4,5,6,7"] {
        let bad_camera = bvhc(&[&"render", &scene, &"-o", &dir.path().join("x.png"), &"--camera", &camera]);
        assert_eq!(bad_camera.status.code(), Some(2), "--camera {camera}: {}", stderr(&bad_camera));
        assert!(stderr(&bad_camera).contains("--camera"), "{}", stderr(&bad_camera));
        assert!(!dir.path().join("x.png").exists());
    }
}

#[test]
fn bad_input_exit_codes_leave_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.bvh");
    let missing = bvhc(&[&dir.path().join("missing.obj"), &"-o", &output]);
    assert_eq!(missing.status.code(), Some(3), "an unreadable input is exit 3, as the README says");
    assert!(stderr(&missing).contains("missing.obj"));
    let unsupported = dir.path().join("scene.fbx");
    std::fs::write(&unsupported, b"Kaydara FBX Binary").unwrap();
    let run = bvhc(&[&unsupported, &"-o", &output]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("unsupported file type"));
    let malformed = dir.path().join("bad.obj");
    std::fs::write(&malformed, b"v 0 0 0\nf 1 2 3\n").unwrap();
    let run = bvhc(&[&malformed, &"-o", &output]);
    assert_eq!(run.status.code(), Some(1));
    assert!(stderr(&run).contains("line 2"), "{}", stderr(&run));
    let unwritable = bvhc(&[&teapot(), &"-o", &dir.path().join("no/such/dir/out.bvh")]);
    assert_eq!(unwritable.status.code(), Some(3), "{}", stderr(&unwritable));
    assert_eq!(files_in(dir.path()), ["bad.obj", "scene.fbx"], "no output and no temporary file");
}

#[test]
fn a_failed_conversion_keeps_the_previous_output() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.bvh");
    std::fs::write(&output, b"previous").unwrap();
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, b"v 0 0 0\nf 1 2 3\n").unwrap();
    assert_eq!(bvhc(&[&bad, &"-o", &output]).status.code(), Some(1));
    assert_eq!(std::fs::read(&output).unwrap(), b"previous");
}

#[test]
fn usage_errors_exit_2() {
    assert_eq!(bvhc(&[]).status.code(), Some(2));
    assert_eq!(bvhc(&[&"--frobnicate"]).status.code(), Some(2));
    assert_eq!(bvhc(&[&teapot()]).status.code(), Some(2), "-o is required");
    assert_eq!(bvhc(&[&teapot(), &"-o", &"x.bvh", &"--preset", &"slowest"]).status.code(), Some(2));
    let help = bvhc(&[&"--help"]);
    assert!(help.status.success() && stdout(&help).contains("Exit codes"));
}
