//! No input panics the loader: random bytes, and mutated and truncated good files (with and without their
//! checksums repaired, so that mutations reach every rule; binary, wide, a converted file with split
//! references and source vertices, and a two-level file), opened, verified and traced, and the hits' source
//! corners looked up.

use bvhc::loader::{BvhFile, Ray};
use bvhc_loader::Trace;
use proptest::prelude::*;

use crate::corrupt::{good_bytes, try_refresh_checksums};
use crate::rules_wide::good_wide_bytes;

/// Opens, verifies and traces a few rays; must return normally whatever `bytes` hold.
fn exercise(bytes: &[u8]) {
    let Ok(file) = BvhFile::from_bytes(bytes) else { return };
    let view = file.view();
    // Large files check their wide sections on a second thread; that path must report the same first rule.
    assert_eq!(view.verify(), view.verify_in_parallel());
    let _ = view.metadata_str();
    for info in view.sections() {
        let _ = info.kind;
    }
    let wide = bvhc::loader::KernelPath::Portable;
    let tracers = [
        Some(view.tracer()),
        Some(view.binary_tracer()),
        view.wide_tracer(wide).map(|w| view.binary_tracer().with_wide(w)),
    ];
    let rays: Vec<Ray> =
        [[1.0, 0.5, 0.25], [-0.0, 0.0, 1.0], [0.3, -1.0, 0.0]].map(|d| Ray::new([-0.1, 0.2, -3.0], d)).to_vec();
    for tracer in tracers.iter().flatten() {
        for ray in &rays {
            if let Some(hit) = tracer.closest_hit(ray) {
                if let Some(corners) = view.source_corners(&hit) {
                    let _ = corners.interpolate(&[[0.0f32; 2]; 4]);
                }
                let _ = tracer.surface(&hit).map(|surface| surface.spawn([0.0, 0.0, 1.0]));
            }
            let _ = tracer.any_hit(ray);
        }
    }
    let (mut hits, mut occluded) = (vec![None; rays.len()], vec![false; rays.len()]);
    view.tracer().closest_hits(&rays, &mut hits);
    view.tracer().any_hits_coherent(&rays, &mut occluded);
    if let Some(wide) = view.wide_tracer(bvhc::loader::KernelPath::best()) {
        let (mut hits, mut occluded) = (vec![None; rays.len()], vec![false; rays.len()]);
        wide.interleaving_streams(true).closest_hits(&rays, &mut hits);
        wide.interleaving_streams(true).any_hits(&rays, &mut occluded);
        wide.closest_hits_coherent(&rays, &mut hits);
        wide.any_hits_coherent(&rays, &mut occluded);
    }
    if let Some(ids) = view.triangle_ids() {
        for &id in ids.iter().take(8) {
            let _ = view.source_range_of(id);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..2048)) {
        exercise(&bytes);
    }

    #[test]
    fn random_bytes_behind_a_valid_magic_never_panic(mut bytes in proptest::collection::vec(any::<u8>(), 64..4096)) {
        bytes[..8].copy_from_slice(b"\x89BVHC\r\n\x1a");
        bytes[8..12].copy_from_slice(&[1, 0, 0, 0]);
        let len = bytes.len() as u64;
        bytes[16..24].copy_from_slice(&len.to_le_bytes());
        exercise(&bytes);
    }

    #[test]
    fn mutated_good_files_never_panic(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..12),
        repair in any::<bool>(),
        base in 0..4usize,
        truncate in proptest::option::of(any::<prop::sample::Index>()),
    ) {
        let mut bytes = match base {
            0 => good_bytes(),
            1 => good_wide_bytes(),
            2 => converted_split_file().to_vec(),
            _ => crate::instances::small_two_level_bytes(),
        };
        for (index, value) in edits {
            let at = index.index(bytes.len());
            bytes[at] = value;
        }
        if repair {
            // Repairing needs a table that lies inside the file; without one the file stays as mutated.
            let _ = try_refresh_checksums(&mut bytes);
        }
        if let Some(cut) = truncate {
            let at = cut.index(bytes.len());
            bytes.truncate(at);
        }
        exercise(&bytes);
    }
}

/// `fixtures/golden/split.obj` converted with the defaults: split references, wide sections, source vertices
/// (format 1.2), every metadata key; made once.
fn converted_split_file() -> &'static [u8] {
    static BYTES: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    BYTES.get_or_init(|| {
        let source = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden/split.obj");
        let dir = tempfile::tempdir().unwrap();
        let output = dir.path().join("split.bvh");
        bvhc::Conversion::new(source, &output).run().unwrap();
        let bytes = std::fs::read(&output).unwrap();
        assert_eq!(BvhFile::from_bytes(&bytes).unwrap().view().version(), (1, 2));
        bytes
    })
}
