//! `bvhc batch` through the door a user takes: a manifest's jobs in order (bad lines reported, the others
//! converted, exit 1), outputs byte-identical to one `bvhc` process a job whatever the thread split, up-to-date
//! jobs skipped, a directory and a glob with output patterns, flags under a manifest's options, and Ctrl-C
//! leaving no partial output.

use std::path::Path;
use std::process::Command;

fn bvhc(args: &[&str], dir: &Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_bvhc")).args(args).current_dir(dir).output().expect("bvhc runs")
}

fn teapot() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj")
}

fn lines(output: &std::process::Output) -> Vec<serde_json::Value> {
    String::from_utf8_lossy(&output.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect()
}

#[test]
fn a_manifest_converts_each_job_as_its_own_process_would_and_reports_each_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir_all(d.join("lib/assets")).unwrap();
    std::fs::copy(teapot(), d.join("lib/assets/teapot.obj")).unwrap();
    let manifest = "# a comment line\n\
        {\"input\": \"assets/teapot.obj\", \"output\": \"out/a.bvh\"}\n\
        {\"input\": \"assets/teapot.obj\", \"output\": \"out/b.bvh\", \"options\": {\"preset\": \"fast\", \"no_splits\": true, \"max_leaf_size\": 4}}\n\
        {\"input\": \"assets/teapot.obj\", \"output\": \"out/c.bvh\", \"options\": {\"splits\": false, \"selection\": \"sum\"}}\n\
        {\"input\": \"assets/missing.obj\", \"output\": \"out/d.bvh\"}\n\
        {\"input\": \"assets/teapot.obj\", \"output\": \"out/e.bvh\", \"options\": {\"split_budget\": 9}}\n\
        {\"input\": \"assets/teapot.obj\", \"output\": \"out/f.bvh\", \"options\": {\"bogus\": 1}}\n\
        {\"input\": \"assets/teapot.obj\", \"output\": \"out/g.bvh\", \"extra\": 1}\n\
        not json\n";
    std::fs::write(d.join("lib/library.jsonl"), manifest).unwrap();
    std::fs::create_dir_all(d.join("lib/out")).unwrap();
    // Run from another folder: paths are relative to the manifest's.
    let run = bvhc(&["batch", "lib/library.jsonl", "--json", "--threads", "2"], d);
    assert_eq!(run.status.code(), Some(1), "{}", String::from_utf8_lossy(&run.stderr));
    let reports = lines(&run);
    let statuses: Vec<&str> = reports.iter().map(|r| r["status"].as_str().unwrap()).collect();
    assert_eq!(statuses, ["converted", "converted", "converted", "failed", "failed", "failed", "failed", "failed"]);
    let sources: Vec<&str> = reports.iter().map(|r| r["source"].as_str().unwrap()).collect();
    assert_eq!(sources[0], "lib/library.jsonl:2");
    assert_eq!(sources[7], "lib/library.jsonl:9");
    assert_eq!(reports[3]["error_kind"], "unreadable");
    assert!(reports[4]["error"].as_str().unwrap().contains("\"split_budget\": 9: expected a fraction from 0 to 4"));
    assert!(reports[5]["error"].as_str().unwrap().contains("bogus: not a conversion option"));
    assert!(reports[6]["error"].as_str().unwrap().contains("\"extra\": not a key of a job"));
    assert!(String::from_utf8_lossy(&run.stderr).contains("lib/library.jsonl:5: "), "each failure on stderr");
    for name in ["d", "e", "f", "g"] {
        assert!(!d.join(format!("lib/out/{name}.bvh")).exists());
    }
    // The same bytes as one process a job, with the same options as flags.
    let flags: [&[&str]; 3] =
        [&[], &["--preset", "fast", "--no-splits", "--max-leaf-size", "4"], &["--no-splits", "--selection", "sum"]];
    for (name, (flags, report)) in ["a", "b", "c"].iter().zip(flags.iter().zip(&reports)) {
        let single = d.join(format!("{name}.bvh"));
        let mut args = vec!["lib/assets/teapot.obj", "-o", single.to_str().unwrap(), "-q"];
        args.extend_from_slice(flags);
        assert!(bvhc(&args, d).status.success());
        let batch = std::fs::read(d.join(format!("lib/out/{name}.bvh"))).unwrap();
        assert_eq!(batch, std::fs::read(&single).unwrap(), "{name}");
        assert_eq!(report["output_hash"], bvhc::import::inputs::content_hash(&batch));
        assert_eq!((report["triangles"].as_u64(), report["threads"].as_u64().is_some()), (Some(6320), true));
    }
    // Again: up to date, the same hashes, on one thread.
    let again = lines(&bvhc(&["batch", "lib/library.jsonl", "--json", "--threads", "1"], d));
    assert_eq!(again[0]["status"], "up_to_date");
    assert_eq!(
        again[..3].iter().map(|r| &r["output_hash"]).collect::<Vec<_>>(),
        reports[..3].iter().map(|r| &r["output_hash"]).collect::<Vec<_>>()
    );
    // Flags apply to every job, a line's options over them; --force converts again.
    let forced = lines(&bvhc(&["batch", "lib/library.jsonl", "--json", "--force", "--preset", "fast"], d));
    assert_eq!(forced[0]["status"], "converted");
    assert_ne!(forced[0]["output_hash"], reports[0]["output_hash"], "job 1 under the fast preset");
    assert_eq!(forced[1]["output_hash"], reports[1]["output_hash"], "job 2 names fast itself");
    // Two jobs naming one output: the later one is refused, the earlier converts.
    let twice = "{\"input\": \"assets/teapot.obj\", \"output\": \"out/x.bvh\"}\n".repeat(2);
    std::fs::write(d.join("lib/twice.jsonl"), twice).unwrap();
    let run = bvhc(&["batch", "lib/twice.jsonl", "--json"], d);
    let statuses: Vec<String> = lines(&run).iter().map(|r| r["status"].as_str().unwrap().to_string()).collect();
    assert_eq!(statuses, ["converted", "failed"]);
    assert!(String::from_utf8_lossy(&run.stderr).contains("also the output of lib/twice.jsonl:1"));
    // Usage and unreadable manifests.
    assert_eq!(bvhc(&["batch", "lib/library.jsonl", "-o", "x/{stem}.bvh"], d).status.code(), Some(2));
    assert_eq!(bvhc(&["batch", "nowhere.jsonl"], d).status.code(), Some(3));
}

#[test]
fn a_directory_and_a_glob_convert_every_scene_with_outputs_by_pattern() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for sub in ["assets", "assets/props"] {
        std::fs::create_dir_all(d.join(sub)).unwrap();
    }
    std::fs::copy(teapot(), d.join("assets/teapot.obj")).unwrap();
    std::fs::copy(teapot(), d.join("assets/props/pot.obj")).unwrap();
    std::fs::write(d.join("assets/notes.txt"), "not a scene").unwrap();
    let run = bvhc(&["batch", "assets", "--preset", "fast", "-q"], d);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(d.join("assets/teapot.bvh").is_file() && d.join("assets/props/pot.bvh").is_file(), "beside each input");
    let run = bvhc(&["batch", "assets/**/*.obj", "-o", "out/{dir}/{stem}-fast.bvh", "--preset", "fast", "--json"], d);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert_eq!(lines(&run).len(), 2);
    let nested = std::fs::read(d.join("out/props/pot-fast.bvh")).unwrap();
    assert_eq!(nested, std::fs::read(d.join("assets/props/pot.bvh")).unwrap());
    assert!(d.join("out/./teapot-fast.bvh").is_file());
    // One output for many inputs is refused before anything runs.
    assert_eq!(bvhc(&["batch", "assets", "-o", "one.bvh"], d).status.code(), Some(2));
}

#[cfg(unix)]
#[test]
fn an_interrupted_batch_leaves_no_partial_output() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Two grids of 720,000 triangles at max-quality: about 10 s each here, so the signal arrives mid-job even on
    // a machine several times faster.
    let n = 600;
    let mut obj = String::new();
    for y in 0..=n {
        for x in 0..=n {
            obj.push_str(&format!("v {x} {y} {}\n", ((x * 7 + y * 13) % 17) as f32 * 0.1));
        }
    }
    for y in 0..n {
        for x in 0..n {
            let i = y * (n + 1) + x + 1;
            obj.push_str(&format!("f {i} {} {}\nf {} {} {}\n", i + 1, i + n + 1, i + 1, i + n + 2, i + n + 1));
        }
    }
    std::fs::write(d.join("grid.obj"), obj).unwrap();
    std::fs::create_dir_all(d.join("out")).unwrap();
    let line = |name: &str| {
        format!(
            "{{\"input\": \"grid.obj\", \"output\": \"out/{name}.bvh\", \"options\": {{\"preset\": \"max-quality\"}}}}\n"
        )
    };
    std::fs::write(d.join("m.jsonl"), line("a") + &line("b")).unwrap();
    let mut child =
        Command::new(env!("CARGO_BIN_EXE_bvhc")).args(["batch", "m.jsonl", "-q"]).current_dir(d).spawn().unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let _ = Command::new("kill").args(["-INT", &child.id().to_string()]).status();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(130), "exits as a process killed by SIGINT");
    let left: Vec<String> = std::fs::read_dir(d.join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    // Finished outputs may stay (whole, verified); nothing else does.
    for name in &left {
        assert!(name == "a.bvh" || name == "b.bvh", "a partial file is left: {left:?}");
        bvhc::loader::BvhFile::read(d.join("out").join(name)).unwrap().view().verify().unwrap();
    }
}
