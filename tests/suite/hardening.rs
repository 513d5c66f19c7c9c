//! Regression tests for the import reproducers of `fixtures/repro/` (from `shared/repro/README.md`): each
//! input behaves as a user expects, with the file, the part and the rule named, and no allocation larger
//! than the documented budget.

use std::io::Write;
use std::path::{Path, PathBuf};

use bvhc::import::memory::MemoryLimit;
use bvhc::import::{ErrorKind, ImportError, ImportLimits, ImportOptions, import};

pub(crate) fn repro(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/repro").join(name)
}

fn import_error(path: &Path, options: &ImportOptions) -> ImportError {
    match import(path, options) {
        Ok(imported) => panic!("{} imported {} triangles", path.display(), imported.soup.triangles.len()),
        Err(error) => error,
    }
}

fn with_limits(limits: ImportLimits) -> ImportOptions {
    ImportOptions { limits, ..Default::default() }
}

#[test]
fn hostile_declared_counts_are_refused_before_allocating() {
    // 642 bytes declaring 44.7M instances: refused by the placement budget before any accessor is decoded (the
    // memory budget, which refuses it too on a machine with less than 11 GB free, is set aside here).
    let memory_unlimited = ImportLimits { max_memory: MemoryLimit::Unlimited, ..Default::default() };
    let error = import_error(&repro("instancing-44M-zero-translations.gltf"), &with_limits(memory_unlimited.clone()));
    assert_eq!(error.kind, ErrorKind::Limit);
    assert!(
        error.message.contains("44739242 mesh placements") && error.message.contains("--max-placements"),
        "{error}"
    );
    assert_eq!(error.location, "node 0");
    // Three accessors of 44.7M zero vertices each (no bufferView): the values of such accessors are held to an
    // eighth of the decoded-values budget, summed over every accessor the scene reads, before any is decoded.
    let error = import_error(&repro("zero-accessors-3.gltf"), &with_limits(memory_unlimited.clone()));
    assert_eq!(error.kind, ErrorKind::Limit);
    assert!(error.message.contains("--max-decoded-values") && error.location == "accessor 0", "{error}");
    assert!(error.message.contains("exceed the import limit of 16777216"), "{error}");
    let small = ImportLimits { max_decoded_values: 1_000_000, ..memory_unlimited.clone() };
    let error = import_error(&repro("zero-accessors-1.gltf"), &with_limits(small));
    assert!(error.message.contains("exceed the import limit of 1000000"), "{error}");
    // With room for one of them, the second crosses the limit: a total over the accessors the scene reads.
    let roomy = ImportLimits { max_decoded_values: 1 << 30, ..memory_unlimited };
    let error = import_error(&repro("zero-accessors-3.gltf"), &with_limits(roomy));
    assert!(
        error.message.contains("exceed the import limit of 134217728") && error.location == "accessor 1",
        "{error}"
    );
    // The triangle budget counts placed triangles, before degenerate ones are dropped.
    let few = ImportLimits { max_triangles: 100, ..Default::default() };
    let error =
        import_error(&PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj"), &with_limits(few));
    assert!(error.kind == ErrorKind::Limit && error.message.contains("--max-triangles"), "{error}");
}

#[test]
fn a_ply_header_cannot_declare_more_than_the_file_holds() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.ply");
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    std::fs::write(&path, header).unwrap();
    let error = import_error(&path, &ImportOptions::default());
    assert!(error.message.contains("declares 4000000000 records"), "{error}");
    let path = dir.path().join("many.ply");
    let mut bytes =
        b"ply\nformat ascii 1.0\nelement vertex 40\nproperty float x\nproperty float y\nproperty float z\nend_header\n"
            .to_vec();
    bytes.extend(std::iter::repeat_n(b"0 0 0\n".as_slice(), 40).flatten());
    std::fs::write(&path, &bytes).unwrap();
    let error = import_error(&path, &with_limits(ImportLimits { max_decoded_values: 60, ..Default::default() }));
    assert!(error.kind == ErrorKind::Limit && error.location == "element 'vertex'", "{error}");
}

/// A gzip stream of `total` bytes made of `chunk` repeated, written without holding it.
fn gzip_bomb(path: &Path, chunk: &[u8], total: usize) {
    let file = std::fs::File::create(path).unwrap();
    let mut gz = flate2::write::GzEncoder::new(file, flate2::Compression::best());
    let mut written = 0;
    while written < total {
        let n = chunk.len().min(total - written);
        gz.write_all(&chunk[..n]).unwrap();
        written += n;
    }
    gz.finish().unwrap();
}

#[test]
fn gzip_bombs_stop_at_the_input_byte_limit() {
    let dir = tempfile::tempdir().unwrap();
    let limits = ImportLimits { max_input_bytes: 4 << 20, ..Default::default() };
    for (name, chunk) in [("zeros.obj.gz", vec![0u8; 1 << 16]), ("vertices.obj.gz", b"v 0 0 0\n".repeat(8192))] {
        let path = dir.path().join(name);
        gzip_bomb(&path, &chunk, 64 << 20);
        assert!(std::fs::metadata(&path).unwrap().len() < 1 << 20, "a bomb is small on disk");
        let error = import_error(&path, &with_limits(limits.clone()));
        assert_eq!(error.kind, ErrorKind::Limit, "{error}");
        assert!(
            error.message.contains("more than 4194304 bytes") && error.message.contains("--max-input-bytes"),
            "{error}"
        );
    }
    // Under the limit, a file of zeros is refused as not an OBJ (it used to give an empty scene).
    let path = dir.path().join("small-zeros.obj.gz");
    gzip_bomb(&path, &[0u8; 4096], 1 << 20);
    let error = import_error(&path, &with_limits(limits));
    assert!(error.location == "line 1" && error.message.contains("NUL byte"), "{error}");
}

#[test]
fn only_regular_files_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("scene.obj");
    std::fs::create_dir(&folder).unwrap();
    let error = import_error(&folder, &ImportOptions::default());
    assert!(error.kind == ErrorKind::Unreadable && error.message.contains("a directory"), "{error}");
    // /dev/zero as a buffer: refused as an absolute path, and when absolute paths are allowed, as not a file.
    let error = import_error(&repro("uri-dev-zero.gltf"), &ImportOptions::default());
    assert!(error.message.contains("absolute path"), "{error}");
    let anywhere = ImportOptions { allow_buffers_outside_input_folder: true, ..Default::default() };
    let error = import_error(&repro("uri-dev-zero.gltf"), &anywhere);
    assert!(error.kind == ErrorKind::Unreadable && error.message.contains("not a regular file"), "{error}");
}

#[cfg(unix)]
#[test]
fn a_fifo_buffer_is_refused_without_blocking() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = dir.path().join("uri-fifo.gltf");
    std::fs::copy(repro("uri-fifo.gltf"), &gltf).unwrap();
    let made = std::process::Command::new("mkfifo").arg(dir.path().join("fifo.bin")).status();
    if !made.is_ok_and(|s| s.success()) {
        crate::skips::skipped(crate::skips::Needs::Tools, "a glTF buffer that is a FIFO (mkfifo is not available)");
        return;
    }
    let error = import_error(&gltf, &ImportOptions::default());
    assert!(error.message.contains("not a regular file"), "{error}");
}

#[test]
fn buffer_uris_stay_under_the_input_folder() {
    let error = import_error(&repro("uri-reads-etc-passwd.gltf"), &ImportOptions::default());
    assert!(
        error.message.contains("leaves the input's folder") && error.message.contains("--allow-outside-buffers"),
        "{error}"
    );
    // A buffer beside the folder is read when allowed, and the metadata names it relatively, never absolutely.
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("scene")).unwrap();
    std::fs::create_dir(dir.path().join("buffers")).unwrap();
    let triangle: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 1., 0.].iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(dir.path().join("buffers/t.bin"), &triangle).unwrap();
    let absolute = dir.path().join("buffers/t.bin").canonicalize().unwrap();
    for uri in ["../buffers/t.bin".to_string(), absolute.to_string_lossy().into_owned()] {
        let gltf = dir.path().join("scene/s.gltf");
        std::fs::write(&gltf, format!(r#"{{"asset":{{"version":"2.0"}},"buffers":[{{"uri":{uri:?},"byteLength":36}}],"bufferViews":[{{"buffer":0,"byteLength":36}}],"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"}}],"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}}}}]}}],"nodes":[{{"mesh":0}}],"scenes":[{{"nodes":[0]}}]}}"#)).unwrap();
        let error = import_error(&gltf, &ImportOptions::default());
        assert!(error.message.contains("--allow-outside-buffers"), "{uri}: {error}");
        let mut options = bvhc::options::ConvertOptions::default();
        options.import.allow_buffers_outside_input_folder = true;
        let output = dir.path().join("out.bvh");
        bvhc::convert::convert_with(&gltf, &output, &options, &mut |_| std::ops::ControlFlow::Continue(())).unwrap();
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        let metadata = crate::common::assert_metadata_matches_schema(&file);
        for input in metadata["inputs"].as_array().unwrap() {
            let name = input["file_name"].as_str().unwrap();
            assert!(!name.starts_with('/') && !Path::new(name).is_absolute(), "{uri}: absolute name {name}");
        }
        assert_eq!(
            metadata["inputs"][1]["file_name"],
            if uri.starts_with("..") { "../buffers/t.bin" } else { "t.bin" }
        );
    }
}

#[test]
fn zero_area_is_judged_the_same_whatever_the_vertex_order() {
    let dir = tempfile::tempdir().unwrap();
    let vertices = ["1e17 1e17 1e17", "0 0 0", "1 2 3"];
    for rotation in 0..3 {
        let path = dir.path().join(format!("r{rotation}.obj"));
        let lines: Vec<String> = (0..3).map(|k| format!("v {}\n", vertices[(k + rotation) % 3])).collect();
        std::fs::write(&path, format!("{}f 1 2 3\n", lines.concat())).unwrap();
        let imported = import(&path, &ImportOptions::default()).unwrap();
        assert_eq!(imported.soup.triangles.len(), 1, "rotation {rotation}: a real triangle is kept");
    }
    let imported = import(&repro("zero-area-misjudged-far-vertex.obj"), &ImportOptions::default()).unwrap();
    assert_eq!(imported.report.degenerate(), 0);
    // Truly collinear points stay degenerate in every order.
    let path = dir.path().join("line.obj");
    std::fs::write(&path, "v 0 0 0\nv 1e17 2e17 3e17\nv 1 2 3\nf 1 2 3\nf 2 3 1\nf 3 1 2\n").unwrap();
    assert_eq!(import(&path, &ImportOptions::default()).unwrap().report.degenerate(), 3);
}

#[test]
fn obj_text_problems_are_named_by_line_or_accepted() {
    for accepted in ["obj-with-bom.obj", "obj-cr-line-endings.obj"] {
        let imported = import(&repro(accepted), &ImportOptions::default()).unwrap();
        assert_eq!(imported.soup.triangles.len(), 1, "{accepted}");
    }
    let error = import_error(&repro("obj-invalid-utf8-name.obj"), &ImportOptions::default());
    assert!(error.location == "line 4" && error.message.contains("not valid UTF-8 (byte 0xFF"), "{error}");
    let error = import_error(&repro("only-nul-bytes.obj"), &ImportOptions::default());
    assert!(error.location == "line 1" && error.message.contains("not a text OBJ file"), "{error}");
}

#[test]
fn huge_polygons_hit_a_documented_limit_and_smaller_ones_convert() {
    let dir = tempfile::tempdir().unwrap();
    let polygon = |n: usize| {
        let mut text = String::new();
        let mut state = 7u64;
        let mut next = || {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..n {
            text += &format!("v {} {} {}\n", next(), next(), next() * 0.01);
        }
        text + "f " + &(1..=n).map(|i| i.to_string()).collect::<Vec<_>>().join(" ") + "\n"
    };
    let path = dir.path().join("big.obj");
    std::fs::write(&path, polygon(100_000)).unwrap();
    let error = import_error(&path, &ImportOptions::default());
    assert!(error.location == "line 100001" && error.message.contains("--max-polygon-vertices"), "{error}");
    let path = dir.path().join("random.obj");
    std::fs::write(&path, polygon(2_000)).unwrap();
    let imported = import(&path, &ImportOptions::default()).unwrap();
    assert_eq!(imported.report.source_triangles, 1_998, "a self-intersecting polygon gives n - 2 triangles");
}

#[test]
fn huge_extents_give_finite_costs() {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("huge.bvh");
    let report = bvhc::convert::convert(&repro("sah-cost-nan-huge-extent.obj"), &output).unwrap();
    assert!(report.cost.cost.is_finite() && report.cost.cost > 0.0, "{:?}", report.cost);
    let file = bvhc::loader::BvhFile::read(&output).unwrap();
    let metadata = crate::common::assert_metadata_matches_schema(&file);
    assert!(metadata["cost"]["sah_cost"].as_f64().is_some_and(f64::is_finite), "{metadata}");
}

#[test]
fn the_optimizer_reproducer_converts_with_every_preset() {
    let dir = tempfile::tempdir().unwrap();
    for preset in bvhc::Preset::ALL {
        let output = dir.path().join("x.bvh");
        let options = bvhc::options::ConvertOptions::preset(preset);
        let report =
            bvhc::convert::convert_with(&repro("optimizer-sibling-of-root-9tri.obj"), &output, &options, &mut |_| {
                std::ops::ControlFlow::Continue(())
            })
            .unwrap();
        assert_eq!(report.triangle_count, 9);
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        file.view().verify().unwrap();
        crate::common::assert_metadata_matches_schema(&file);
    }
}
