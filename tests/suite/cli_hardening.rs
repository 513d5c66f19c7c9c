//! Regression tests for the command-line reproducers (`shared/repro/README.md`, second table): full disks and
//! closed pipes, exit codes, outputs that are inputs or not regular files, file modes, and signals.

use std::path::Path;
use std::process::{Command, Stdio};

use crate::cli::{bvhc, files_in, stderr, stdout, teapot};
use crate::hardening::repro;

fn no_panic(output: &std::process::Output) {
    assert!(!stderr(output).contains("panicked"), "{}", stderr(output));
    assert_ne!(output.status.code(), Some(101), "{}", stderr(output));
}

fn good_bvh(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("good.bvh");
    let run = bvhc(&[&repro("obj-with-bom.obj"), &"-o", &path, &"-q"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    path
}

/// Runs bvhc with stdout (or stderr) redirected to /dev/full.
fn to_dev_full(args: &[&dyn AsRef<std::ffi::OsStr>], stream_is_stderr: bool) -> std::process::Output {
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").expect("/dev/full");
    let mut command = Command::new(env!("CARGO_BIN_EXE_bvhc"));
    command.args(args.iter().map(|a| a.as_ref()));
    if stream_is_stderr {
        command.stderr(full).stdout(Stdio::piped());
    } else {
        command.stdout(full).stderr(Stdio::piped());
    }
    command.output().unwrap()
}

#[test]
fn a_full_disk_on_stdout_or_stderr_is_exit_3_without_panic() {
    if !Path::new("/dev/full").exists() {
        crate::skips::skipped(crate::skips::Needs::Tools, "a full disk on stdout and stderr (no /dev/full)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let good = good_bvh(dir.path());
    let png = dir.path().join("x.png");
    let out = dir.path().join("again.bvh");
    let scene = teapot();
    let cases: Vec<Vec<&dyn AsRef<std::ffi::OsStr>>> = vec![
        vec![&"info", &good],
        vec![&"info", &good, &"--json"],
        vec![&"verify", &good],
        vec![&"render", &good, &"-o", &png, &"--width", &"8", &"--height", &"8"],
        vec![&scene, &"-o", &out, &"--json", &"--preset", &"fast"],
    ];
    for args in &cases {
        let run = to_dev_full(args, false);
        no_panic(&run);
        assert_eq!(run.status.code(), Some(3), "{:?}", stderr(&run));
        assert!(stderr(&run).contains("cannot write to standard output"), "{}", stderr(&run));
    }
    let run = to_dev_full(&[&"verify", &dir.path().join("missing.bvh")], true);
    no_panic(&run);
    assert_eq!(run.status.code(), Some(3));
}

#[test]
fn a_closed_pipe_ends_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let good = good_bvh(dir.path());
    for args in [vec!["info", "--json"], vec!["info"], vec!["verify"]] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_bvhc"))
            .args(&args)
            .arg(&good)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take()); // the reader is gone before bvhc writes: `| head -c 0`
        let run = child.wait_with_output().unwrap();
        no_panic(&run);
        assert_eq!(run.status.code(), Some(0), "{args:?}: {}", stderr(&run));
        assert_eq!(stderr(&run), "", "{args:?}: quiet");
    }
}

#[test]
fn unreadable_inputs_are_exit_3() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("x.bvh");
    std::fs::create_dir(dir.path().join("folder.obj")).unwrap();
    std::fs::create_dir(dir.path().join("some folder")).unwrap();
    for input in [dir.path().join("missing.obj"), dir.path().join("missing.xyz")] {
        let run = bvhc(&[&input, &"-o", &output]);
        assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
        assert!(stderr(&run).contains("cannot read"), "{}", stderr(&run));
    }
    // A folder is unreadable whatever its name: with or without a scene extension, named a directory.
    for input in [dir.path().join("folder.obj"), dir.path().join("some folder")] {
        let run = bvhc(&[&input, &"-o", &output]);
        assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
        assert!(stderr(&run).contains("cannot read: a directory"), "{}", stderr(&run));
    }
    assert!(!output.exists());
}

/// What a newcomer met: a glTF whose buffer is missing, an output in a folder that does not exist (named as
/// such, not by the temporary file that could not be made there), a `.bvh` path that is a directory (its path
/// once in the message): exit 3, as the README says.
#[test]
fn a_missing_buffer_or_output_folder_is_exit_3_naming_what_is_missing() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = dir.path().join("m.gltf");
    std::fs::write(
        &gltf,
        r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"nothere.bin","byteLength":36}],
            "bufferViews":[{"buffer":0,"byteLength":36}],
            "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],
            "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]}"#,
    )
    .unwrap();
    let run = bvhc(&[&gltf, &"-o", &dir.path().join("m.bvh")]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert!(stderr(&run).contains("nothere.bin"), "{}", stderr(&run));
    let missing = dir.path().join("not").join("there").join("x.bvh");
    let run = bvhc(&[&crate::cli::teapot(), &"-o", &missing]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert!(stderr(&run).contains("folder") && stderr(&run).contains("does not exist"), "{}", stderr(&run));
    assert!(!stderr(&run).contains(".bvhc-"), "the temporary file is not the user's business: {}", stderr(&run));
    let folder = dir.path().join("folder.bvh");
    std::fs::create_dir(&folder).unwrap();
    let run = bvhc(&[&"verify", &folder]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert_eq!(stderr(&run).matches("folder.bvh").count(), 1, "{}", stderr(&run));
    assert!(stderr(&run).contains("is a directory"), "{}", stderr(&run));
}

/// `--help` speaks numbers, not rustdoc links, and lists each flag under its stage.
#[test]
fn help_has_no_rustdoc_links_and_flags_under_their_stages() {
    for command in [&[][..], &["verify"][..], &["info"][..], &["render"][..], &["trace"][..], &["options"][..]] {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> =
            command.iter().map(|c| c as &dyn AsRef<std::ffi::OsStr>).collect();
        args.push(&"--help");
        let help = String::from_utf8(bvhc(&args).stdout).unwrap();
        assert!(!help.contains("[`") && !help.contains("`]"), "{command:?}: a rustdoc link in --help");
    }
    let help = String::from_utf8(bvhc(&[&"--help"]).stdout).unwrap();
    let section = |flag: &str| {
        let at = help.find(flag).unwrap_or_else(|| panic!("{flag} in --help"));
        help[..at].lines().rev().find(|l| !l.starts_with(' ') && l.ends_with(':')).unwrap().to_string()
    };
    assert_eq!(section("--tune-rays"), "Leaf layout:");
    assert_eq!(section("--train-rays"), "Leaf layout:");
    assert_eq!(section("--gpu-layout"), "Output:");
    assert!(help.contains("1,048,576"), "the instancing threshold as a number");
}

#[test]
fn outputs_that_are_inputs_or_not_regular_files_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let same = dir.path().join("same.obj");
    std::fs::copy(repro("obj-with-bom.obj"), &same).unwrap();
    let original = std::fs::read(&same).unwrap();
    let run = bvhc(&[&same, &"-o", &same]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert!(stderr(&run).contains("the output is one of the inputs"), "{}", stderr(&run));
    assert_eq!(std::fs::read(&same).unwrap(), original, "the input is intact");
    // A glTF file's own buffer as the output.
    let gltf = dir.path().join("scene.gltf");
    let triangle: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.].iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(dir.path().join("scene.bin"), &triangle).unwrap();
    std::fs::write(&gltf, r#"{"asset":{"version":"2.0"},"buffers":[{"uri":"scene.bin","byteLength":36}],"bufferViews":[{"buffer":0,"byteLength":36}],"accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}],"meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"nodes":[{"mesh":0}],"scenes":[{"nodes":[0]}]}"#).unwrap();
    let run = bvhc(&[&gltf, &"-o", &dir.path().join("scene.bin")]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert_eq!(std::fs::read(dir.path().join("scene.bin")).unwrap(), triangle);
    // render onto its own input.
    let good = good_bvh(dir.path());
    let before = std::fs::read(&good).unwrap();
    let run = bvhc(&[&"render", &good, &"-o", &good]);
    assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
    assert_eq!(std::fs::read(&good).unwrap(), before);
    // A device node (as root it used to be replaced by a regular file).
    if Path::new("/dev/null").exists() {
        let run = bvhc(&[&same, &"-o", &"/dev/null"]);
        assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
        assert!(stderr(&run).contains("not a regular file"), "{}", stderr(&run));
        assert!(!std::fs::metadata("/dev/null").unwrap().is_file());
    }
    #[cfg(unix)]
    {
        let fifo = dir.path().join("o.bvh");
        if Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
            let run = bvhc(&[&same, &"-o", &fifo]); // used to hang in the up-to-date check
            assert_eq!(run.status.code(), Some(3), "{}", stderr(&run));
        } else {
            crate::skips::skipped(crate::skips::Needs::Tools, "part: a FIFO output (mkfifo is not available)");
        }
    }
}

#[cfg(unix)]
#[test]
fn new_outputs_get_the_umask_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    for (umask, mode) in [("022", 0o644), ("077", 0o600), ("002", 0o664)] {
        let output = dir.path().join(format!("u{umask}.bvh"));
        let script = format!("umask {umask}; exec \"$0\" \"$1\" -o \"$2\" -q --preset fast");
        let run = Command::new("sh")
            .args(["-c", &script, env!("CARGO_BIN_EXE_bvhc")])
            .arg(teapot())
            .arg(&output)
            .output()
            .unwrap();
        assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
        assert_eq!(std::fs::metadata(&output).unwrap().permissions().mode() & 0o777, mode, "umask {umask}");
    }
}

#[test]
fn bad_option_values_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("x.bvh");
    let scene = teapot();
    for bad in [
        ["--time-budget", "nan"],
        ["--time-budget=-1", ""],
        ["--time-budget", "1e300"],
        ["--threads", "100000"],
        ["--threads", "0"],
        ["--animation=,", ""],
        ["--animation=0,", ""],
        ["--animation=,0", ""],
    ] {
        let args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&scene, &"-o", &output, &bad[0], &bad[1]];
        let args: Vec<&dyn AsRef<std::ffi::OsStr>> = args.into_iter().filter(|a| !a.as_ref().is_empty()).collect();
        let run = bvhc(&args);
        assert_eq!(run.status.code(), Some(2), "{bad:?}: {}", stderr(&run));
        assert!(stderr(&run).contains("invalid value"), "{bad:?}: {}", stderr(&run));
    }
    assert!(!output.exists());
    let run = bvhc(&[&"options", &"--animation", &","]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
    assert!(stderr(&run).contains("an empty clip name"), "{}", stderr(&run));
}

#[test]
fn the_summary_says_whether_degenerate_triangles_were_kept() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("x.bvh");
    let kept = bvhc(&[&repro("keep-degenerate-message.obj"), &"-o", &output, &"--keep-degenerate"]);
    assert!(stdout(&kept).contains("2 triangles (1 degenerate kept)"), "{}", stdout(&kept));
    let dropped = bvhc(&[&repro("keep-degenerate-message.obj"), &"-o", &output, &"--force"]);
    assert!(stdout(&dropped).contains("1 triangles (1 degenerate dropped)"), "{}", stdout(&dropped));
}

/// A scene that takes the optimizer long enough to be interrupted (max-quality on 80,000 triangles: seconds).
fn slow_scene(dir: &Path) -> std::path::PathBuf {
    let path = dir.join("slow.obj");
    let mut text = String::new();
    for (i, t) in crate::common::random_triangles(77, 80_000, 100.0).iter().enumerate() {
        for v in t {
            text += &format!("v {} {} {}\n", v[0], v[1], v[2]);
        }
        text += &format!("f {} {} {}\n", 3 * i + 1, 3 * i + 2, 3 * i + 3);
    }
    std::fs::write(&path, text).unwrap();
    path
}

#[cfg(unix)]
#[test]
fn signals_leave_no_temporary_file_and_stale_ones_are_swept() {
    let dir = tempfile::tempdir().unwrap();
    let scene = slow_scene(dir.path());
    let out_dir = dir.path().join("out");
    std::fs::create_dir(&out_dir).unwrap();
    let output = out_dir.join("slow.bvh");
    std::fs::write(&output, b"previous").unwrap();
    for (signal, code) in [("INT", 130), ("TERM", 143), ("HUP", 129)] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_bvhc"))
            .arg(&scene)
            .arg("-o")
            .arg(&output)
            .args(["--preset", "max-quality", "--force", "-q"])
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(400));
        // Stand in for the temporary file a write in progress holds at the moment the signal arrives.
        let pending = out_dir.join(format!(
            "{}{}-pending{}",
            bvhc::loader::write::TEMPORARY_PREFIX,
            child.id(),
            bvhc::loader::write::TEMPORARY_SUFFIX
        ));
        std::fs::write(&pending, b"partial").unwrap();
        let sent = Command::new("kill").arg(format!("-{signal}")).arg(child.id().to_string()).status().unwrap();
        assert!(sent.success());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(code), "SIG{signal}");
        assert_eq!(files_in(&out_dir), ["slow.bvh"], "SIG{signal}: no temporary file left");
        assert_eq!(std::fs::read(&output).unwrap(), b"previous", "SIG{signal}: the output is untouched");
    }
    // A killed run's temporary file (its process is gone) is swept by the next write into that folder.
    let stale = out_dir.join(format!(
        "{}{}-x{}",
        bvhc::loader::write::TEMPORARY_PREFIX,
        u32::MAX - 1,
        bvhc::loader::write::TEMPORARY_SUFFIX
    ));
    std::fs::write(&stale, b"stale").unwrap();
    let run = bvhc(&[&teapot(), &"-o", &out_dir.join("teapot.bvh"), &"-q", &"--preset", &"fast"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(!stale.exists() || !cfg!(target_os = "linux"), "stale temporary file swept");
}

/// Whether process `pid` holds a file open beside `output`, in its folder, other than `output` itself (its
/// descriptors in `/proc`, Linux): the temporary file of the output being written, named or unnamed (an
/// `O_TMPFILE` file shows as `folder/#inode (deleted)`).
#[cfg(target_os = "linux")]
fn writes_beside(pid: u32, output: &Path) -> bool {
    let Ok(descriptors) = std::fs::read_dir(format!("/proc/{pid}/fd")) else { return false };
    let folder = output.parent().unwrap();
    descriptors
        .flatten()
        .any(|fd| std::fs::read_link(fd.path()).is_ok_and(|target| target.parent() == Some(folder) && target != output))
}

#[cfg(target_os = "linux")]
#[test]
fn sigkill_while_the_output_is_written_leaves_nothing_behind() {
    // SIGKILL runs no handler: only an unnamed temporary file (O_TMPFILE) leaves nothing. The conversion is
    // killed the moment it holds its temporary file open beside the output, that is while it writes it.
    let dir = tempfile::tempdir().unwrap();
    let scene = slow_scene(dir.path());
    let out_dir = dir.path().join("out").canonicalize().unwrap_or_else(|_| {
        std::fs::create_dir(dir.path().join("out")).unwrap();
        dir.path().join("out").canonicalize().unwrap()
    });
    let output = out_dir.join("slow.bvh");
    std::fs::write(&output, b"previous").unwrap();
    let mut caught = 0;
    for _ in 0..5 {
        let mut child = Command::new(env!("CARGO_BIN_EXE_bvhc"))
            .arg(&scene)
            .arg("-o")
            .arg(&output)
            .args(["--preset", "fast", "--force", "-q"])
            .spawn()
            .unwrap();
        while child.try_wait().unwrap().is_none() {
            if writes_beside(child.id(), &output) {
                child.kill().unwrap(); // SIGKILL
                caught += 1;
                break;
            }
        }
        let status = child.wait().unwrap();
        if status.success() {
            // It finished before the poll saw the write: the output is the new file; start again from "previous".
            std::fs::write(&output, b"previous").unwrap();
            continue;
        }
        assert_eq!(files_in(&out_dir), ["slow.bvh"], "no temporary file left by SIGKILL during the write");
        assert_eq!(std::fs::read(&output).unwrap(), b"previous", "the output is untouched");
        if caught >= 2 {
            break;
        }
    }
    if caught == 0 {
        crate::skips::skipped(
            crate::skips::Needs::Machine,
            "SIGKILL during the write (the write was never seen in progress: the file system or a fast disk)",
        );
    } else {
        eprintln!("{caught} conversions killed while writing their output");
    }
}

/// Decodes an RGB8 PNG written by `bvhc render`.
fn read_png(path: &Path) -> (usize, usize, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    (info.width as usize, info.height as usize, pixels)
}

#[test]
fn the_heat_map_has_a_legend_and_interiors_are_shown_from_inside() {
    let dir = tempfile::tempdir().unwrap();
    let teapot_bvh = dir.path().join("teapot.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &teapot_bvh, &"-q", &"--preset", &"fast"]).status.success());
    let image = dir.path().join("heat.png");
    let run = bvhc(&[&"render", &teapot_bvh, &"-o", &image, &"--width", &"320", &"--height", &"240", &"--heatmap"]);
    assert!(run.status.success(), "{}", stderr(&run));
    assert!(
        stdout(&run).contains("camera from outside") && stdout(&run).contains("legend at the bottom"),
        "{}",
        stdout(&run)
    );
    let most: u32 = stdout(&run).split("yellow to red (").nth(1).unwrap().split(' ').next().unwrap().parse().unwrap();
    assert!(most > 0);
    let (width, height, pixels) = read_png(&image);
    let pixel = |x: usize, y: usize| &pixels[3 * (y * width + x)..3 * (y * width + x) + 3];
    // The colour bar: blue at its left end (0 steps), red at its right end (the maximum).
    let bar_y = height - 22 + 5;
    let (left, right) = (pixel(8, bar_y), pixel(width - 9, bar_y));
    assert!(left[2] > left[0] && left[2] > left[1], "left end {left:?} is blue");
    assert!(right[0] > 200 && right[1] < 60 && right[2] < 60, "right end {right:?} is red");
    // White label pixels below the bar.
    let labels = (height - 10..height).any(|y| (0..width).any(|x| pixel(x, y) == [255, 255, 255]));
    assert!(labels, "the legend has labels");
    // A closed building seen from outside is one box: the default view goes inside it.
    match crate::common::scene("trimesh-no-indices-3storybuilding/no_indices_3storybuilding.glb") {
        Some(building) => {
            let bvh = dir.path().join("building.bvh");
            assert!(bvhc(&[&building, &"-o", &bvh, &"-q"]).status.success());
            let run = bvhc(&[&"render", &bvh, &"-o", &dir.path().join("b.png"), &"--width", &"64", &"--height", &"48"]);
            assert!(stdout(&run).contains("camera from inside the scene's box"), "{}", stdout(&run));
        }
        None => {
            crate::skips::skipped(crate::skips::Needs::Scenes, "part: the render from inside the 3-storey building")
        }
    }
}
