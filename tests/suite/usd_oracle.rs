//! bvhc's OpenUSD import against Pixar's own library: `scripts/usd-triangles.py` composes each stage with
//! usd-core and writes the world-space triangles USD's renderers draw; bvhc's flattened import (every placement
//! expanded, degenerate triangles kept) must hold the same triangles, as sets, each corner within 1e-6 of the
//! scene's extent and in the same winding, both ways: the shared USD scenes, and a stage usd-core writes with
//! every mesh feature the import handles (`scripts/usd-feature-stage.py`) as usda, usdc and usdz, at the default
//! time and at a time between samples.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use bvhc::import::{ImportOptions, Instancing, import};

use super::common::scene;
use super::skips::{Needs, skipped};

/// The Python with usd-core (`scripts/usd-core.sh`), or `None` after reporting the skip.
fn usd_python(what: &str) -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let python = std::env::var_os("BVHC_USD_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target/usd/venv/bin/python"));
    let works = Command::new(&python).args(["-c", "import pxr.Usd, numpy"]).output().is_ok_and(|o| o.status.success());
    if !works {
        skipped(Needs::Usd, format!("{what} (scripts/usd-core.sh installs usd-core into target/usd/venv)"));
        return None;
    }
    Some(python)
}

/// usd-core's triangles of `stage` at `time`: 9 coordinates each.
fn oracle(python: &Path, stage: &Path, time: Option<f64>) -> Vec<[f64; 9]> {
    let out = tempfile::NamedTempFile::new().expect("temp file");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/usd-triangles.py");
    let mut command = Command::new(python);
    command.arg(&script).arg(stage).arg(out.path());
    if let Some(t) = time {
        command.args(["--time", &t.to_string()]);
    }
    let output = command.output().expect("the oracle runs");
    assert!(
        output.status.success(),
        "usd-triangles.py {}: {}",
        stage.display(),
        String::from_utf8_lossy(&output.stderr)
    );
    let bytes = std::fs::read(out.path()).expect("oracle output");
    bytes
        .chunks_exact(72)
        .map(|t| std::array::from_fn(|i| f64::from_le_bytes(t[8 * i..8 * i + 8].try_into().unwrap())))
        .collect()
}

/// bvhc's flattened triangles of `stage` at `time`.
fn imported(stage: &Path, time: Option<f64>) -> Vec<[f64; 9]> {
    let options =
        ImportOptions { instancing: Instancing::Never, keep_degenerate: true, time_code: time, ..Default::default() };
    let import = import(stage, &options).unwrap_or_else(|e| panic!("{e}"));
    assert!(import.instanced.is_empty());
    (0..import.soup.triangles.len())
        .map(|t| {
            let v = import.soup.vertices(t);
            std::array::from_fn(|i| f64::from(v[i / 3][i % 3]))
        })
        .collect()
}

/// Whether `a` is `b` within `tolerance`, in one of its three rotations (the winding kept).
fn same_triangle(a: &[f64; 9], b: &[f64; 9], tolerance: f64) -> bool {
    (0..3).any(|r| (0..9).all(|i| (a[i] - b[(i + 3 * r) % 9]).abs() <= tolerance))
}

/// A triangle's centroid, which does not depend on the order of its corners.
fn centroid(t: &[f64; 9]) -> [f64; 3] {
    [0, 1, 2].map(|a| (t[a] + t[a + 3] + t[a + 6]) / 3.0)
}

/// Asserts that `ours` and `theirs` hold the same triangles, each corner within 1e-6 of the scene's extent and
/// each triangle matched once.
fn assert_same_triangles(name: &str, ours: &[[f64; 9]], theirs: &[[f64; 9]]) {
    assert_same_triangles_within(name, ours, theirs, 1e-6);
}

/// [`assert_same_triangles`] within `relative` of the scene's extent.
fn assert_same_triangles_within(name: &str, ours: &[[f64; 9]], theirs: &[[f64; 9]], relative: f64) {
    assert_eq!(
        ours.len(),
        theirs.len(),
        "{name}: bvhc imports {} triangles, usd-core draws {}",
        ours.len(),
        theirs.len()
    );
    let mut low = [f64::INFINITY; 3];
    let mut high = [f64::NEG_INFINITY; 3];
    for t in theirs {
        for i in 0..9 {
            low[i % 3] = low[i % 3].min(t[i]);
            high[i % 3] = high[i % 3].max(t[i]);
        }
    }
    let extent = (0..3).map(|a| high[a] - low[a]).fold(0.0, f64::max).max(1e-30);
    let tolerance = relative * extent;
    // Buckets by centroid on a grid of cells much larger than the tolerance; a match is searched in the cell
    // and its neighbours.
    let cell = 1e-4 * extent;
    let key = |t: &[f64; 9]| centroid(t).map(|c| (c / cell).floor() as i64);
    let mut buckets: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, t) in ours.iter().enumerate() {
        buckets.entry(key(t)).or_default().push(i);
    }
    let mut used = vec![false; ours.len()];
    for (n, t) in theirs.iter().enumerate() {
        let k = key(t);
        let mut found = None;
        'search: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    for &i in buckets.get(&[k[0] + dx, k[1] + dy, k[2] + dz]).into_iter().flatten() {
                        if !used[i] && same_triangle(&ours[i], t, tolerance) {
                            found = Some(i);
                            break 'search;
                        }
                    }
                }
            }
        }
        let i = found.unwrap_or_else(|| panic!("{name}: usd-core's triangle {n} {t:?} is not among bvhc's"));
        used[i] = true;
    }
}

#[test]
fn shared_usd_stages_import_the_triangles_usd_core_draws() {
    let Some(python) = usd_python("the shared USD stages against usd-core") else { return };
    for stage in [
        "usd-teapot/Teapot.usd",
        "usd-animated-cube/AnimatedCube.usdz",
        "usd-brainstem/BrainStem.usdz",
        "usd-mini-car-kit/USD_Mini_Car_Kit/assets/vehicles/vehicleVariants.usda",
        "usd-open-chess-set/chess_set.usda",
    ] {
        let Some(path) = scene(stage) else { return };
        assert_same_triangles(stage, &imported(&path, None), &oracle(&python, &path, None));
    }
    // Time-sampled transforms, and UsdSkel skinning at the animation's samples and between them. Between
    // samples the joints' rotations are slerped in f32, by openusd and by usd-core with different formulas: the
    // skinned corners then agree within 1e-5 of the extent (measured: 4.3e-6 at time code 300.25), at samples
    // within 1e-6.
    for (stage, time, relative) in [
        ("usd-animated-cube/AnimatedCube.usdz", 0.0, 1e-6),
        ("usd-animated-cube/AnimatedCube.usdz", 7.5, 1e-6),
        ("usd-animated-cube/AnimatedCube.usdz", 30.0, 1e-6),
        ("usd-brainstem/BrainStem.usdz", 0.0, 1e-6),
        ("usd-brainstem/BrainStem.usdz", 300.25, 1e-5),
        ("usd-brainstem/BrainStem.usdz", 1290.0, 1e-5),
    ] {
        let Some(path) = scene(stage) else { return };
        let name = format!("{stage} at {time}");
        assert_same_triangles_within(
            &name,
            &imported(&path, Some(time)),
            &oracle(&python, &path, Some(time)),
            relative,
        );
    }
}

#[test]
fn a_stage_with_every_mesh_feature_imports_as_usd_core_draws_it_in_every_format() {
    let Some(python) = usd_python("a stage written by usd-core against usd-core") else { return };
    let dir = tempfile::tempdir().expect("temp dir");
    let formats = ["usda", "usdc", "usdz"].map(|ext| dir.path().join(format!("features.{ext}")));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/usd-feature-stage.py");
    let output = Command::new(&python).arg(script).args(&formats).output().expect("the stage writer runs");
    assert!(output.status.success(), "usd-feature-stage.py: {}", String::from_utf8_lossy(&output.stderr));
    for stage in &formats {
        for time in [None, Some(5.0), Some(10.0)] {
            let name = format!("{} at {time:?}", stage.display());
            let theirs = oracle(&python, stage, time);
            assert!(theirs.len() > 90, "{name}: the stage draws {} triangles", theirs.len());
            assert_same_triangles(&name, &imported(stage, time), &theirs);
        }
    }
}

#[test]
fn brainstem_as_usd_and_as_gltf_stands_in_the_same_pose_at_the_same_time() {
    // The same asset in both formats: the USD stage's time codes run at its 37 a second from the glTF clip's
    // start; skinned by UsdSkel and by glTF's skins, the two imports agree within f32 rounding of the files' own
    // values (measured: 1.2e-5 of the extent at most, per coordinate).
    let (Some(usd), Some(gltf)) = (scene("usd-brainstem/BrainStem.usdz"), scene("khr-brainstem/BrainStem.gltf")) else {
        return;
    };
    for time_code in [0.0, 300.0, 1000.0] {
        let gltf_options = ImportOptions {
            instancing: Instancing::Never,
            keep_degenerate: true,
            pose: Some(bvhc::import::PoseSelector {
                clip: bvhc::import::ClipSelector::Index(0),
                seconds: time_code / 37.0,
            }),
            ..Default::default()
        };
        let gltf_import = import(&gltf, &gltf_options).unwrap();
        let theirs: Vec<[f64; 9]> = (0..gltf_import.soup.triangles.len())
            .map(|t| {
                let v = gltf_import.soup.vertices(t);
                std::array::from_fn(|i| f64::from(v[i / 3][i % 3]))
            })
            .collect();
        let name = format!("BrainStem at time code {time_code}");
        assert_same_triangles_within(&name, &imported(&usd, Some(time_code)), &theirs, 2e-5);
    }
}
