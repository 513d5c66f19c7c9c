//! Alpha-tested glTF scenes, end to end: the converter marks exactly the triangles of `MASK` and `BLEND`
//! materials not opaque (checked against the glTF's materials as the AO example reads them), a filtered tracer
//! asks its filter about those alone, the cut-outs honour each material's `alphaCutoff`, and the AO example
//! renders the scenes with their cut-outs, alike from one- and two-level files (the vase places its flowers
//! twice).

use bvhc_loader::Trace;
use std::path::{Path, PathBuf};
use std::process::Command;

use bvhc::loader::{BvhFile, Ray, filter::Candidate, filter::FilterScope};

use crate::cli::bvhc;

#[path = "../../examples/ao/cutouts.rs"]
#[allow(dead_code)]
mod cutouts;

use cutouts::{AlphaTest, Cutouts};

const VASE: &str = "khr-glass-vase-flowers/GlassVaseFlowers.gltf";
const BLEND_TEST: &str = "khr-alpha-blend-mode-test/AlphaBlendModeTest.gltf";

fn convert(gltf: &Path, out: &Path, extra: &[&str]) -> BvhFile {
    let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&gltf, &"-o", &out, &"-q"];
    args.extend(extra.iter().map(|a| a as &dyn AsRef<std::ffi::OsStr>));
    let run = bvhc(&args);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    BvhFile::read(out).unwrap()
}

#[test]
fn triangles_of_alpha_tested_materials_and_no_others_are_marked_not_opaque() {
    for scene in [VASE, BLEND_TEST] {
        let Some(gltf) = crate::common::scene(scene) else { return };
        let cutouts = Cutouts::read(&gltf).unwrap();
        let tested = cutouts.alpha_tests();
        let dir = tempfile::tempdir().unwrap();
        for (name, extra) in [("one-level", &[][..]), ("two-level", &["--instancing", "always"][..])] {
            let file = convert(&gltf, &dir.path().join(format!("{name}.bvh")), extra);
            let view = file.view();
            // The vase places its flowers twice; the blend-mode test places each mesh once (one level either way).
            assert_eq!(view.two_level().is_some(), name == "two-level" && scene == VASE, "{scene} {name}");
            let flags = view.triangle_flags().expect("an alpha-tested scene has the triangle_flags section");
            let ids = view.triangle_ids().unwrap();
            let mut marked = 0;
            let mut marked_ids = std::collections::BTreeSet::new();
            for (record, &id) in ids.iter().enumerate() {
                let range = view.source_range_of(id).unwrap();
                let alpha_tested = tested.iter().any(|&(m, p, _)| (m, p) == (range.mesh_index, range.primitive_index));
                assert_eq!(view.is_not_opaque(record as u32), alpha_tested, "{scene} {name}: record {record}");
                marked += usize::from(alpha_tested);
                if alpha_tested {
                    marked_ids.insert(id);
                }
            }
            assert!(marked > 0 && marked < flags.len(), "{scene} {name}: {marked} of {} marked", flags.len());
            // `bvhc info` counts them.
            let path = dir.path().join(format!("{name}.bvh"));
            let text = crate::cli::stdout(&bvhc(&[&"info", &path]));
            assert!(
                text.contains(&format!(
                    "opacity: {marked} of {} triangle records ({} distinct triangles) not opaque",
                    flags.len(),
                    marked_ids.len()
                )),
                "{text}"
            );
            let json = crate::cli::stdout(&bvhc(&[&"info", &path, &"--json"]));
            let info: serde_json::Value = serde_json::from_str(&json).unwrap();
            assert_eq!(info["not_opaque_count"].as_u64(), Some(marked as u64), "{scene} {name}");
            // Split triangles have several records and one id: the distinct triangles are the distinct ids.
            assert_eq!(info["not_opaque_triangle_count"].as_u64(), Some(marked_ids.len() as u64), "{scene} {name}");
        }
        // Forced either way by --opacity.
        let opaque = convert(&gltf, &dir.path().join("opaque.bvh"), &["--opacity", "opaque"]);
        assert!((0..opaque.view().triangles().len() as u32).all(|r| !opaque.view().is_not_opaque(r)), "{scene}");
        let filtered = convert(&gltf, &dir.path().join("filtered.bvh"), &["--opacity", "filtered"]);
        assert!((0..filtered.view().triangles().len() as u32).all(|r| filtered.view().is_not_opaque(r)), "{scene}");
    }
}

/// Rays straight at each of the blend-mode test's five boards (x = -3, -1.5, 0, 1.5, 3: opaque, blend, cutoff
/// 0.25, default 0.5, 0.75; one label texture), on a grid: how many of those that hit the board keep their hit.
fn board_coverage(file: &BvhFile, cutouts: &Cutouts) -> Vec<f64> {
    let view = file.view();
    let tracer = view.tracer();
    let asked = std::sync::atomic::AtomicUsize::new(0);
    let keeps = |candidate: &Candidate<'_>| {
        asked.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        assert!(view.is_not_opaque(candidate.triangle_index), "the filter is asked about an opaque triangle");
        cutouts.keeps(&view, candidate)
    };
    let filtered = tracer.filtered(&keeps, FilterScope::NotOpaque);
    let coverage = [-3.0f32, -1.5, 0.0, 1.5, 3.0]
        .iter()
        .map(|&x| {
            let (mut on_board, mut kept) = (0, 0);
            for i in 0..40 {
                for j in 0..80 {
                    let origin = [x - 0.5 + (i as f32 + 0.5) / 40.0, 0.15 + 1.77 * (j as f32 + 0.5) / 80.0, 1.0];
                    let ray = Ray::new(origin, [0.0, 0.0, -1.0]);
                    // The boards are at z = 0, the backdrop behind them.
                    if tracer.closest_hit(&ray).is_some_and(|hit| (hit.t - 1.0).abs() < 1e-3) {
                        on_board += 1;
                        kept += usize::from(filtered.closest_hit(&ray).is_some_and(|hit| (hit.t - 1.0).abs() < 1e-3));
                    }
                }
            }
            assert!(on_board > 3000, "board at x = {x}: {on_board} of 3200 rays hit it");
            kept as f64 / on_board as f64
        })
        .collect();
    assert!(asked.into_inner() > 0);
    coverage
}

#[test]
fn cut_outs_honour_each_materials_alpha_cutoff() {
    let Some(gltf) = crate::common::scene(BLEND_TEST) else { return };
    let cutouts = Cutouts::read(&gltf).unwrap();
    let tests: Vec<AlphaTest> = cutouts.alpha_tests().into_iter().map(|(.., test)| test).collect();
    for expected in [0.25, 0.5, 0.75] {
        assert!(tests.contains(&AlphaTest::Mask { cutoff: expected }), "{tests:?}");
    }
    assert!(tests.contains(&AlphaTest::Blend), "{tests:?}");
    let dir = tempfile::tempdir().unwrap();
    let file = convert(&gltf, &dir.path().join("test.bvh"), &[]);
    let [opaque, blend, cutoff25, cutoff50, cutoff75] = board_coverage(&file, &cutouts)[..] else { unreachable!() };
    assert_eq!(opaque, 1.0);
    // The same texture's alpha: the lower the cutoff, the more of the board stays; stochastic blending keeps
    // some of every part.
    assert!(cutoff25 > cutoff50 && cutoff50 > cutoff75 && cutoff75 > 0.05, "{cutoff25} {cutoff50} {cutoff75}");
    assert!(blend > 0.05 && blend < 1.0, "{blend}");
}

fn example() -> Option<PathBuf> {
    let exe = std::env::current_exe().unwrap();
    let example = exe.parent().and_then(|deps| deps.parent()).map(|profile| profile.join("examples/ao"));
    let found = example.filter(|path| path.is_file());
    if found.is_none() {
        crate::skips::skipped(
            crate::skips::Needs::Build,
            "the ao example (not built beside the tests; cargo test builds it)",
        );
    }
    found
}

/// The example's grey pixels for `bvh`, with `--gltf` when given.
fn render(example: &Path, bvh: &Path, gltf: Option<&Path>) -> (Vec<u8>, String) {
    let png = bvh.with_extension("png");
    let mut command = Command::new(example);
    command.arg(bvh).arg(&png).args(["--width", "160", "--height", "120", "--samples", "8"]);
    if let Some(gltf) = gltf {
        command.arg("--gltf").arg(gltf);
    }
    let run = command.output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut pixels).unwrap();
    (pixels, String::from_utf8_lossy(&run.stdout).into_owned())
}

#[test]
fn the_ao_example_renders_alpha_cut_outs() {
    let Some(example) = example() else { return };
    for (scene, summary) in [
        (VASE, "1 primitives with alphaMode MASK, 1 with BLEND"),
        (BLEND_TEST, "3 primitives with alphaMode MASK, 2 with BLEND"),
    ] {
        let Some(gltf) = crate::common::scene(scene) else { return };
        let dir = tempfile::tempdir().unwrap();
        let one = dir.path().join("one.bvh");
        let two = dir.path().join("two.bvh");
        convert(&gltf, &one, &[]);
        convert(&gltf, &two, &["--instancing", "always"]);
        let (solid, _) = render(&example, &one, None);
        let (cut, stdout) = render(&example, &one, Some(&gltf));
        assert!(stdout.contains(summary), "{stdout}");
        let (cut_two_level, _) = render(&example, &two, Some(&gltf));
        // Background pixels are 40: cutting out shows more of it (or the backdrop, lit differently).
        let background = |pixels: &[u8]| pixels.iter().filter(|&&p| p == 40).count();
        let changed = solid.iter().zip(&cut).filter(|(a, b)| a != b).count();
        assert!(changed > solid.len() / 50, "{scene}: {changed} pixels change with cut-outs");
        assert!(background(&cut) >= background(&solid), "{scene}");
        // One- and two-level files give the same picture, up to noise: a two-level hit differs by rounding at
        // the instance's transform, which shifts the row's random occlusion directions, and the stochastic blend
        // hashes the placement.
        let lit_mean = |pixels: &[u8]| {
            let lit: Vec<f64> = pixels.iter().filter(|&&p| p != 40).map(|&p| f64::from(p)).collect();
            lit.iter().sum::<f64>() / lit.len() as f64
        };
        let (a, b) = (background(&cut) as f64, background(&cut_two_level) as f64);
        assert!((a - b).abs() <= 0.01 * cut.len() as f64, "{scene}: background {a} one-level, {b} two-level");
        let (a, b) = (lit_mean(&cut), lit_mean(&cut_two_level));
        assert!((a - b).abs() < 4.0, "{scene}: mean lit pixel {a} one-level, {b} two-level");
    }
}
