//! The conversion's memory budget: a small glTF that places one mesh many times, flattened, is refused before
//! its triangles are held, quickly, with an error naming the file, the estimate and `--max-memory`; instanced
//! (the default for it), or within the budget, it converts.

use bvhc_loader::Trace;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::cli::{bvhc, stderr};

/// Writes `many.gltf` (and its buffer) placing a grid mesh of `2 * side^2` triangles `placements` times.
fn many_placements(dir: &Path, side: u32, placements: usize) -> PathBuf {
    let mut bytes = Vec::new();
    for y in 0..=side {
        for x in 0..=side {
            for c in [x as f32, y as f32, 0.0] {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    let positions_len = bytes.len();
    let at = |x: u32, y: u32| y * (side + 1) + x;
    for y in 0..side {
        for x in 0..side {
            for v in [at(x, y), at(x + 1, y), at(x, y + 1), at(x + 1, y), at(x + 1, y + 1), at(x, y + 1)] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    std::fs::write(dir.join("grid.bin"), &bytes).unwrap();
    let vertex_count = (side + 1) * (side + 1);
    let index_count = 6 * side * side;
    let nodes: Vec<String> = (0..placements)
        .map(|i| format!(r#"{{"mesh":0,"translation":[{}.0,0.0,0.0]}}"#, 2 * side as usize * i))
        .collect();
    let scene: Vec<String> = (0..placements).map(|i| i.to_string()).collect();
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[{}]}}],"nodes":[{}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "buffers":[{{"uri":"grid.bin","byteLength":{}}}],
        "bufferViews":[{{"buffer":0,"byteLength":{positions_len}}},{{"buffer":0,"byteOffset":{positions_len},"byteLength":{}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{vertex_count},"type":"VEC3","min":[0,0,0],"max":[{side},{side},0]}},
        {{"bufferView":1,"componentType":5125,"count":{index_count},"type":"SCALAR"}}]}}"#,
        scene.join(","),
        nodes.join(","),
        bytes.len(),
        bytes.len() - positions_len,
    );
    let path = dir.join("many.gltf");
    std::fs::write(&path, json).unwrap();
    path
}

#[test]
fn a_scene_over_the_memory_budget_is_refused_before_it_is_held() {
    let dir = tempfile::tempdir().unwrap();
    // 10,000 placements of a 4,232-triangle mesh: 42.3M triangles, about 10 GB to convert.
    let scene = many_placements(dir.path(), 46, 10_000);
    assert!(std::fs::metadata(&scene).unwrap().len() < 600_000);
    let output = dir.path().join("many.bvh");
    // Flattened (every placement stored), it is refused at once.
    let run = bvhc(&[&scene, &"-o", &output, &"--max-memory", &"2G", &"--instancing", &"never"]);
    assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
    let message = stderr(&run);
    for part in ["many.gltf", "42320000 placed triangles need about 10.7G", "2.0G --max-memory allows", "--max-memory"]
    {
        assert!(message.contains(part), "{part:?} missing from {message}");
    }
    assert!(!output.exists());
    // Instanced (the default decides so: the copies add 42M triangles), the mesh is stored once and the scene
    // converts within the same budget: one mesh, 10,000 instances, every placement traced.
    let run = bvhc(&[&scene, &"-o", &output, &"--max-memory", &"2G"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let file = bvhc::loader::BvhFile::read(&output).unwrap();
    let two_level = file.view().two_level().expect("a two-level file");
    assert_eq!((two_level.meshes.len(), two_level.instances.len()), (1, 10_000));
    assert_eq!(two_level.placed_record_count(), 42_320_000);
    let tracer = file.view().tracer();
    for copy in [0u32, 4_321, 9_999] {
        // Straight down onto copy `copy`'s grid (copies are 92 units apart on x).
        let hit =
            tracer.closest_hit(&bvhc::loader::Ray::new([92.0 * copy as f32 + 10.5, 10.25, 5.0], [0.0, 0.0, -1.0]));
        assert_eq!(hit.map(|h| (h.instance_index, h.t)), Some((Some(copy), 5.0)), "copy {copy}");
    }
    std::fs::remove_file(&output).unwrap();
    // Within a budget the same mesh placed a few times converts.
    let small = many_placements(dir.path(), 46, 3);
    let run = bvhc(&[&small, &"-o", &output, &"--max-memory", &"2G"]);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    // Comparing candidate trees (max-quality) is estimated higher: 12,696 flattened triangles fit 104M for one
    // tree (100M + 270 bytes a triangle) but not for candidates (400 bytes a triangle).
    let never: &[&dyn AsRef<std::ffi::OsStr>] = &[&"--instancing", &"never"];
    let run = bvhc(
        &[&[&small as &dyn AsRef<std::ffi::OsStr>, &"-o", &output, &"--max-memory", &"104M", &"--no-splits"], never]
            .concat(),
    );
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    let max_quality: &[&dyn AsRef<std::ffi::OsStr>] =
        &[&small, &"-o", &output, &"--max-memory", &"104M", &"--preset", &"max-quality"];
    let run = bvhc(&[max_quality, never].concat());
    assert_eq!(run.status.code(), Some(1), "{}", stderr(&run));
    assert!(stderr(&run).contains("12696 placed triangles") && stderr(&run).contains("400 bytes a triangle"));
    // Where the flattened scene does not fit, `auto` instances the repeated mesh, whatever it saves: it converts.
    let run = bvhc(max_quality);
    assert_eq!(run.status.code(), Some(0), "{}", stderr(&run));
    assert!(bvhc::loader::BvhFile::read(&output).unwrap().view().two_level().is_some());
    // A bad size is a usage error.
    let run = bvhc(&[&small, &"-o", &output, &"--max-memory", &"lots"]);
    assert_eq!(run.status.code(), Some(2), "{}", stderr(&run));
}

#[test]
fn the_default_budget_follows_the_address_space_limit() {
    let Ok(prlimit) = which_prlimit() else {
        crate::skips::skipped(
            crate::skips::Needs::Tools,
            "the address-space budget (prlimit of util-linux is not installed)",
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = many_placements(dir.path(), 46, 10_000);
    let output = dir.path().join("many.bvh");
    let run = Command::new(prlimit)
        .arg("--as=4000000000")
        .arg(env!("CARGO_BIN_EXE_bvhc"))
        .args([scene.as_os_str(), "-o".as_ref(), output.as_os_str(), "--instancing".as_ref(), "never".as_ref()])
        .output()
        .unwrap();
    let message = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(1), "{message}");
    assert!(message.contains("this process may use") && message.contains("--max-memory"), "{message}");
    assert!(!output.exists());
    // Instanced, the same scene converts under the same limit.
    let run = Command::new(which_prlimit().unwrap())
        .arg("--as=4000000000")
        .arg(env!("CARGO_BIN_EXE_bvhc"))
        .args([scene.as_os_str(), "-o".as_ref(), output.as_os_str()])
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(0), "{}", String::from_utf8_lossy(&run.stderr));
}

fn which_prlimit() -> Result<PathBuf, ()> {
    ["/usr/bin/prlimit", "/bin/prlimit"].iter().map(PathBuf::from).find(|p| p.exists()).ok_or(())
}
