//! No animated asset panics the posing paths: random bytes, floats (NaN, infinities, negative and huge
//! values, zero) and JSON numbers of skinned, morphed and rigidly animated glTFs changed, then the asset imported
//! at a random time of a clip (`--pose`), its clips listed (`--animation`'s spans), and a file converted from the
//! unchanged asset refit to it (`bvhc refit --pose`, Python's `Scene.pose`): each either succeeds, with finite
//! positions, or fails with an error. Hand-made strips (`animation_hostile.rs`) and the shared samples.

use std::path::{Path, PathBuf};

use bvhc::import::{ClipSelector, ImportOptions, PoseSelector, animation_clips, import};
use bvhc::loader::BvhFile;
use proptest::prelude::*;

use crate::animation_hostile::Strip;
use crate::common::scenes_dir;
use crate::import_mutation::{probe_numbers, replace_number};

/// An animated glTF of the shared scenes: its JSON and its one buffer file.
const SAMPLES: &[(&str, &str)] = &[
    ("khr-simple-skin/SimpleSkin.gltf", ""),
    ("khr-animated-morph-cube-quantized/AnimatedMorphCube.gltf", "AnimatedMorphCube.bin"),
    ("khr-cesium-milk-truck/CesiumMilkTruck.gltf", "CesiumMilkTruck_data.bin"),
    ("khr-fox/Fox.gltf", "Fox.bin"),
];

/// Floats that break animation data: NaN, infinities, a negative weight, zero, huge and subnormal values.
fn probe_floats() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(-1.0f32),
        Just(0.0f32),
        Just(1e30f32),
        Just(1e-40f32),
        (-4.0f32..4.0),
    ]
}

/// Copies `main` and the files beside it into `dir`, with the JSON's numbers and one buffer's floats changed;
/// returns the copied main file's path.
fn mutated_copy(
    dir: &Path,
    main: &Path,
    buffer: &str,
    numbers: &[(prop::sample::Index, serde_json::Value)],
    floats: &[(prop::sample::Index, f32)],
) -> PathBuf {
    let folder = main.parent().unwrap();
    for entry in std::fs::read_dir(folder).unwrap().flatten() {
        std::fs::copy(entry.path(), dir.join(entry.file_name())).unwrap();
    }
    let mut json: serde_json::Value = serde_json::from_slice(&std::fs::read(main).unwrap()).unwrap();
    for (index, replacement) in numbers {
        let count = replace_number(&mut json, usize::MAX, replacement);
        replace_number(&mut json, index.index(count.max(1)), replacement);
    }
    let path = dir.join(main.file_name().unwrap());
    std::fs::write(&path, json.to_string()).unwrap();
    let buffers: Vec<String> = match buffer {
        "" => json["buffers"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|b| b["uri"].as_str().map(String::from))
            .collect(),
        name => vec![name.to_string()],
    };
    for (k, (index, value)) in floats.iter().enumerate() {
        let Some(name) = buffers.get(k % buffers.len().max(1)) else { break };
        let Ok(mut bytes) = std::fs::read(dir.join(name)) else { continue };
        if bytes.len() >= 4 {
            let at = 4 * index.index(bytes.len() / 4);
            bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
            std::fs::write(dir.join(name), bytes).unwrap();
        }
    }
    path
}

/// Runs every posing path on `asset` (a mutated copy of `clean`, converted once to `converted`): only a panic,
/// or a success with positions that are not finite, fails.
fn pose_every_way(asset: &Path, converted: &Path, seconds: f64) {
    let pose = PoseSelector { clip: ClipSelector::Index(0), seconds };
    let options = ImportOptions { pose: Some(pose.clone()), ..Default::default() };
    if let Ok(imported) = import(asset, &options) {
        assert!(imported.soup.positions.iter().flatten().all(|c| c.is_finite()), "{}", asset.display());
    }
    let _ = animation_clips(asset, &ImportOptions::default());
    let Ok(mut file) = BvhFile::read(converted) else { return };
    if let Ok(placed) = bvhc::posed::placed_pose(&file.view(), asset, &Default::default(), Some(&pose)) {
        assert!(placed.positions.iter().flatten().flatten().all(|c| c.is_finite()));
        let _ = placed.apply(&mut file, 1);
    }
}

/// The unchanged asset converted without split references into `dir` (what `bvhc refit` starts from).
fn converted(dir: &Path, asset: &Path) -> PathBuf {
    let output = dir.join("clean.bvh");
    let conversion = bvhc::Conversion::new(asset, &output).preset(bvhc::Preset::Fast);
    let overrides = bvhc::options::Overrides { splits: Some(false), ..Default::default() };
    conversion.overrides(overrides).run().unwrap_or_else(|e| panic!("{}: {e}", asset.display()));
    output
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 160, ..ProptestConfig::default() })]

    #[test]
    fn mutated_animated_assets_never_panic_a_pose(
        which in any::<prop::sample::Index>(),
        numbers in proptest::collection::vec((any::<prop::sample::Index>(), probe_numbers()), 0..3),
        floats in proptest::collection::vec((any::<prop::sample::Index>(), probe_floats()), 0..6),
        seconds in 0.0f64..4.0,
    ) {
        // The shared samples, where they are on this machine, and the hand-made strip.
        let source = tempfile::tempdir().unwrap();
        let shared = scenes_dir().map_or(0, |_| SAMPLES.len());
        let (main, buffer) = match which.index(shared + 1) {
            k if k < shared => (scenes_dir().unwrap().join(SAMPLES[k].0), SAMPLES[k].1),
            _ => (Strip::new().write(source.path(), "strip", |_| {}), "strip.bin"),
        };
        let dir = tempfile::tempdir().unwrap();
        let clean = tempfile::tempdir().unwrap();
        let original = mutated_copy(clean.path(), &main, buffer, &[], &[]);
        let converted = converted(clean.path(), &original);
        let asset = mutated_copy(dir.path(), &main, buffer, &numbers, &floats);
        pose_every_way(&asset, &converted, seconds);
    }
}
