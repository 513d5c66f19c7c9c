//! OpenUSD import through the doors a user takes, without Pixar's library (tests/suite/usd_oracle.rs holds the
//! triangles to usd-core's): instancing under each policy, purposes, the time code, what the metadata and
//! `bvhc info` record, the files an up-to-date check covers, and hostile stages (a zip bomb, cycles, missing
//! layers, malformed layers, byte-level mutations), each refused with a clear error and never a panic.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

use bvhc::import::{ErrorKind, ImportOptions, Instancing, Pose, PoseSelector, Purposes, import};

use super::common::scene;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/usd").join(name)
}

fn bvhc(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_bvhc")).args(args).output().expect("bvhc runs")
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn the_fixture_stage_keeps_its_instances_and_point_instancer_as_instances_unless_told_not_to() {
    for stage in ["features.usda", "features.usdc"] {
        let path = fixture(stage);
        let flat = import(&path, &ImportOptions { instancing: Instancing::Never, ..Default::default() }).unwrap();
        assert!(flat.instanced.is_empty());
        for mode in [Instancing::Auto, Instancing::Always] {
            let kept = import(&path, &ImportOptions { instancing: mode, ..Default::default() }).unwrap();
            // The native instances' prototype (3 visible instances) and the point instancer's two prototypes
            // (3 visible instances each: one of 7 is an invisible id).
            let placements: Vec<usize> = kept.instanced.iter().map(|m| m.placements.len()).collect();
            assert_eq!(placements, [3, 3, 3], "{stage} under {mode:?}");
            assert_eq!(kept.report.placed_triangles, flat.report.placed_triangles, "{stage}");
            let record = kept.stage.as_ref().unwrap();
            let roots: Vec<&str> =
                kept.instanced.iter().map(|m| record.prims[m.mesh_index as usize].as_str()).collect();
            assert_eq!(roots, ["/World/Inst0", "/World/Forest/Protos/Tree", "/World/Forest/Protos/Rock"]);
            let placers: Vec<&str> =
                kept.instanced[1].placements.iter().map(|p| record.prims[p.node_index as usize].as_str()).collect();
            assert_eq!(placers, ["/World/Forest"; 3]);
            let instances: Vec<u32> = kept.instanced[1].placements.iter().map(|p| p.gpu_instance_index).collect();
            assert_eq!(instances, [0, 4, 6], "the point instancer's instances 0, 4 and 6 draw the tree (2 is hidden)");
            assert_eq!(record.meters_per_unit, Some(0.01));
            assert_eq!(record.up_axis.as_deref(), Some("Z"));
        }
    }
}

#[test]
fn purposes_choose_the_geometry_and_the_time_code_moves_it() {
    let path = fixture("features.usda");
    let count = |options: ImportOptions| {
        let options = ImportOptions { instancing: Instancing::Never, keep_degenerate: true, ..options };
        import(&path, &options).unwrap().soup.triangles.len()
    };
    let default = count(ImportOptions::default());
    let with_proxy = count(ImportOptions { purposes: "render,proxy".parse().unwrap(), ..Default::default() });
    let everything = count(ImportOptions { purposes: "render,proxy,guide".parse().unwrap(), ..Default::default() });
    let bare = Purposes { render: false, proxy: false, guide: false };
    let without_render = count(ImportOptions { purposes: bare, ..Default::default() });
    // /World/Proxy and /World/Guide are 8 triangles each, /World/RenderScope/Mesh 8.
    assert_eq!((with_proxy - default, everything - with_proxy, default - without_render), (8, 8, 8));
    assert!("render,shadow".parse::<Purposes>().unwrap_err().contains("'shadow' is not a USD purpose"));
    // /World/Moving is at z = 10 by default, and moves from x = 0 to 4 between time codes 0 and 10.
    let at = |time_code| {
        let import = import(&path, &ImportOptions { time_code, ..Default::default() }).unwrap();
        let source = import.stage.unwrap().prims.iter().position(|p| p == "/World/Moving/Mesh").unwrap() as u32;
        let range = import.soup.sources.iter().find(|r| r.mesh_index == source).copied().unwrap();
        let t = import.soup.source_ids.iter().position(|&id| id == range.first_source_triangle).unwrap();
        import.soup.vertices(t)
    };
    assert_ne!(at(None), at(Some(0.0)));
    let (start, middle, end) = (at(Some(0.0)), at(Some(5.0)), at(Some(10.0)));
    for corner in 0..3 {
        for axis in 0..3 {
            let halfway = 0.5 * (start[corner][axis] + end[corner][axis]);
            assert!((middle[corner][axis] - halfway).abs() < 1e-4, "linear interpolation at time code 5");
        }
    }
}

#[test]
fn a_pose_of_the_wrong_kind_is_refused_by_name() {
    // A stage's one clip is its time codes: clip 0 at 2.5 s is time code 2.5 * timeCodesPerSecond (24 here).
    let stage = fixture("features.usda");
    let clip = |clip, seconds| ImportOptions { pose: Some(PoseSelector { clip, seconds }), ..Default::default() };
    let by_clip = import(&stage, &clip(bvhc::import::ClipSelector::Index(0), 2.5 / 24.0)).unwrap();
    let by_code = import(&stage, &ImportOptions { time_code: Some(2.5), ..Default::default() }).unwrap();
    assert_eq!(by_clip.soup, by_code.soup);
    let error = import(&stage, &clip(bvhc::import::ClipSelector::Index(1), 1.0)).unwrap_err();
    assert!(error.to_string().contains("has one clip, its time codes"), "{error}");
    let Some(box_gltf) = scene("khr-box/Box.gltf") else { return };
    let error = import(&box_gltf, &ImportOptions { time_code: Some(3.0), ..Default::default() }).unwrap_err();
    assert!(error.to_string().contains("a glTF pose is CLIP@SECONDS"), "{error}");
    assert_eq!("12.5".parse::<Pose>().unwrap(), Pose::TimeCode(12.5));
    assert!(matches!("Walk@0.5".parse::<Pose>().unwrap(), Pose::Clip(_)));
    assert!("soon".parse::<Pose>().is_err());
}

#[test]
fn the_command_line_converts_a_stage_records_it_and_lists_every_layer_it_read() {
    let dir = tempfile::tempdir().unwrap();
    let geometry = write(
        dir.path(),
        "geometry.usda",
        "#usda 1.0\n(\n    defaultPrim = \"Tri\"\n)\ndef Mesh \"Tri\"\n{\n    int[] faceVertexCounts = [3]\n    \
         int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n}\n",
    );
    let stage = write(
        dir.path(),
        "stage.usda",
        "#usda 1.0\n(\n    metersPerUnit = 0.5\n)\ndef \"A\" (\n    references = @./geometry.usda@\n)\n{\n}\n\
         def \"B\" (\n    prepend payload = @./geometry.usda@\n)\n{\n    double3 xformOp:translate = (2, 0, 0)\n    \
         uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}\n",
    );
    let output = dir.path().join("stage.bvh");
    let outcome = bvhc::convert::Conversion::new(&stage, &output).run().unwrap();
    assert_eq!(outcome.files_read, [stage.clone(), geometry.clone()]);
    let run = bvhc(&["info", output.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&run.stdout);
    assert!(text.contains("usd stage: 2 prims named, 0.5 m a unit"), "{text}");
    assert!(text.contains("input: geometry.usda"), "{text}");
    assert!(text.contains("source 0: ids 0..1: /A\n") && text.contains("source 1: ids 1..2: /B\n"), "{text}");
    // A changed referenced layer makes the file out of date.
    std::fs::write(&geometry, std::fs::read_to_string(&geometry).unwrap().replace("(0, 1, 0)]", "(0, 2, 0)]")).unwrap();
    assert!(!bvhc::convert::Conversion::new(&stage, &output).run().unwrap().up_to_date);
    let run = bvhc(&[stage.to_str().unwrap(), "-o", output.to_str().unwrap(), "--pose", "walk@1"]);
    assert!(!run.status.success());
    assert!(String::from_utf8_lossy(&run.stderr).contains("has one clip, its time codes"));
}

#[cfg(unix)]
#[test]
fn a_stage_gives_the_same_bytes_however_its_path_is_spelled_and_its_material_x_is_never_read() {
    let dir = tempfile::tempdir().unwrap();
    let set = dir.path().join("set");
    std::fs::create_dir_all(set.join("parts")).unwrap();
    write(
        &set.join("parts"),
        "geometry.usda",
        "#usda 1.0\n(\n    defaultPrim = \"Tri\"\n)\ndef Mesh \"Tri\"\n{\n    int[] faceVertexCounts = [3]\n    \
         int[] faceVertexIndices = [0, 1, 2]\n    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n}\n",
    );
    // A MaterialX document that exists: no layer format reads it, and a BVH needs no materials.
    write(&set, "look.mtlx", "<?xml version=\"1.0\"?>\n<materialx version=\"1.38\"/>\n");
    write(
        &set,
        "stage.usda",
        "#usda 1.0\ndef \"A\" (\n    references = @./parts/geometry.usda@\n)\n{\n}\n\
         def \"Looks\" (\n    references = @./look.mtlx@</Materials>\n)\n{\n}\n",
    );
    let link = dir.path().join("link");
    std::os::unix::fs::symlink(&set, &link).unwrap();
    let spellings = [set.join("stage.usda"), link.join("stage.usda"), set.join("parts/../stage.usda")];
    let mut written = Vec::new();
    for (n, stage) in spellings.iter().enumerate() {
        let output = dir.path().join(format!("{n}.bvh"));
        let outcome = bvhc::convert::Conversion::new(stage, &output).run().unwrap();
        assert_eq!(outcome.files_read.len(), 2, "{stage:?}: {:?}", outcome.files_read);
        assert!(outcome.files_read[1].ends_with("parts/geometry.usda"), "{:?}", outcome.files_read);
        written.push(std::fs::read(&output).unwrap());
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        let metadata = super::common::assert_metadata_matches_schema(&file);
        let inputs: Vec<&str> =
            metadata["inputs"].as_array().unwrap().iter().map(|i| i["file_name"].as_str().unwrap()).collect();
        assert_eq!(inputs, ["stage.usda", "parts/geometry.usda"], "{stage:?}");
        assert_eq!(metadata["usd"]["unread_material_layers"], serde_json::json!(["look.mtlx"]), "{stage:?}");
    }
    assert!(written.windows(2).all(|w| w[0] == w[1]), "the same bytes from every spelling of the stage's path");
}

#[test]
fn the_chess_set_converts_to_a_two_level_file_whose_info_names_its_prims() {
    let Some(chess) = scene("usd-open-chess-set/chess_set.usda") else { return };
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("chess.bvh");
    let run = bvhc(&[chess.to_str().unwrap(), "-o", output.to_str().unwrap(), "--preset", "fast"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let file = bvhc::loader::BvhFile::read(&output).unwrap();
    let two_level = file.view().two_level().expect("two-level");
    assert_eq!((two_level.meshes.len(), two_level.instances.len()), (3, 17));
    let metadata = super::common::assert_metadata_matches_schema(&file);
    assert_eq!(metadata["two_level"]["placed_triangle_count"], 1_429_623);
    let inputs = metadata["inputs"].as_array().unwrap();
    assert_eq!(inputs.len(), 29, "the stage and its 28 asset layers: {inputs:?}");
    let unread = metadata["usd"]["unread_material_layers"].as_array().unwrap();
    assert!(unread.iter().any(|l| l == "assets/Pawn/Pawn_mat.mtlx"), "{unread:?}");
    let info = bvhc(&["info", output.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        text.contains("instance 1: mesh 1 (/ChessSet/Black/Pawns/Pawn), placed by /ChessSet/Black/Pawns instance 0")
    );
    assert!(text.contains(": /ChessSet/White/Pawns/Pawn/Geom_Body/Render"), "{text}");
}

/// The error of importing `path`.
fn refused(path: &Path) -> bvhc::import::ImportError {
    import(path, &ImportOptions::default()).map(|i| i.soup.triangles.len()).unwrap_err()
}

#[test]
fn hostile_stages_are_refused_with_the_layer_and_prim_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A zip bomb: a package entry that inflates to 200 MB from a few hundred KB.
    let bomb = d.join("bomb.usdz");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&bomb).unwrap());
    let deflated = zip::write::SimpleFileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("root.usda", deflated).unwrap();
    zip.write_all(b"#usda 1.0\n").unwrap();
    for _ in 0..200 {
        zip.write_all(&[b' '; 1 << 20]).unwrap();
    }
    zip.finish().unwrap();
    let error = refused(&bomb);
    assert!(
        error.message.contains("is compressed (Deflated); a USDZ package stores its files uncompressed"),
        "{error}"
    );

    let sublayer = write(d, "self.usda", "#usda 1.0\n(\n    subLayers = [@./self.usda@]\n)\n");
    assert!(refused(&sublayer).message.contains("sublayer cycle"), "{}", refused(&sublayer));
    write(d, "b.usda", "#usda 1.0\ndef Xform \"B\" (\n    references = @./a.usda@</A>\n)\n{\n}\n");
    let cycle = write(d, "a.usda", "#usda 1.0\ndef Xform \"A\" (\n    references = @./b.usda@</B>\n)\n{\n}\n");
    assert!(refused(&cycle).message.contains("cycle at /A"), "{}", refused(&cycle));
    let missing = write(d, "missing.usda", "#usda 1.0\ndef Xform \"A\" (\n    references = @./absent.usda@\n)\n{\n}\n");
    let error = refused(&missing);
    assert_eq!(error.kind, ErrorKind::Unreadable);
    assert!(error.message.contains("absent.usda") && error.message.contains("at /A"), "{error}");
    let payload =
        write(d, "payload.usda", "#usda 1.0\ndef Xform \"P\" (\n    prepend payload = @./gone.usdc@\n)\n{\n}\n");
    assert!(refused(&payload).message.contains("gone.usdc"), "{}", refused(&payload));
    let garbage = write(d, "garbage.usda", "not a layer");
    assert!(refused(&garbage).message.contains("USDA"), "{}", refused(&garbage));
    let bad_mesh = write(
        d,
        "bad.usda",
        "#usda 1.0\ndef Mesh \"M\"\n{\n    int[] faceVertexCounts = [3]\n    int[] faceVertexIndices = [0, 1, 9]\n    \
         point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n}\n",
    );
    let error = refused(&bad_mesh);
    assert_eq!(error.location, "prim /M");
    assert!(error.message.contains("faceVertexIndices holds 9, not a point index (the mesh has 3 points)"), "{error}");
    let bad_op = write(
        d,
        "op.usda",
        "#usda 1.0\ndef Xform \"X\"\n{\n    double3 xformOp:shear = (1, 2, 3)\n    \
         uniform token[] xformOpOrder = [\"xformOp:shear\"]\n}\n",
    );
    assert!(refused(&bad_op).message.contains("'shear' is not an op kind USD defines"), "{}", refused(&bad_op));
    // A crate file cut anywhere is an error, never a panic.
    let crate_bytes = std::fs::read(fixture("features.usdc")).unwrap();
    for cut in [0, 8, 88, 200, crate_bytes.len() / 2, crate_bytes.len() - 1] {
        let cut_file = d.join(format!("cut{cut}.usdc"));
        std::fs::write(&cut_file, &crate_bytes[..cut]).unwrap();
        let error = refused(&cut_file);
        assert!(!error.message.is_empty(), "cut at {cut}");
    }
}

#[test]
fn mutated_text_layers_give_an_answer_or_an_error_never_a_panic() {
    let bytes = std::fs::read(fixture("features.usda")).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut rng = super::common::rng(61);
    let (mut imported, mut refused) = (0, 0);
    for round in 0..300 {
        use rand::RngExt;
        let mut mutated = bytes.clone();
        let at = rng.random_range(0..mutated.len());
        match round % 3 {
            0 => mutated[at] ^= 1 << rng.random_range(0..8),
            1 => mutated[at] = *b"0123456789-.e[](),\"@".get(rng.random_range(0..20)).unwrap(),
            _ => mutated.truncate(at),
        }
        let path = dir.path().join(format!("m{round}.usda"));
        std::fs::write(&path, &mutated).unwrap();
        match import(&path, &ImportOptions::default()) {
            Ok(_) => imported += 1,
            Err(e) => {
                assert!(!e.message.is_empty());
                refused += 1
            }
        }
    }
    assert!(imported > 0 && refused > 0, "{imported} imported, {refused} refused");
}

#[test]
fn a_stage_is_converted_for_its_animation_over_its_time_codes() {
    // BrainStem as USD (time codes at 37 a second) and as glTF: the same poses, so trees of nearly equal cost.
    let (Some(usd), Some(gltf)) = (scene("usd-brainstem/BrainStem.usdz"), scene("khr-brainstem/BrainStem.gltf")) else {
        return;
    };
    let clips = bvhc::import::animation_clips(&usd, &ImportOptions::default()).unwrap();
    assert_eq!(clips.len(), 1);
    assert_eq!(clips[0].name.as_deref(), Some(bvhc::import::TIME_CODES_CLIP));
    assert!((clips[0].end - 1290.5600395202637 / 37.0).abs() < 1e-9);
    let dir = tempfile::tempdir().unwrap();
    let mut costs = Vec::new();
    for input in [&usd, &gltf] {
        let output = dir.path().join("animated.bvh");
        let run = bvhc(&[
            input.to_str().unwrap(),
            "-o",
            output.to_str().unwrap(),
            "--animation",
            "--animation-poses",
            "4",
            "--force",
        ]);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        let metadata = super::common::assert_metadata_matches_schema(&file);
        assert_eq!(metadata["animation"]["poses"].as_array().unwrap().len(), 4);
        costs.push(metadata["animation"]["expected_wide_cost"].as_f64().unwrap());
    }
    assert!((costs[0] / costs[1] - 1.0).abs() < 0.01, "USD {} against glTF {}", costs[0], costs[1]);
}

#[test]
fn instances_of_different_prototypes_are_different_units() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = |name: &str, counts: &str, indices: &str, points: &str| {
        format!(
            "class \"{name}\"\n{{\n    def Mesh \"M\"\n    {{\n        int[] faceVertexCounts = [{counts}]\n        \
             int[] faceVertexIndices = [{indices}]\n        point3f[] points = [{points}]\n    }}\n}}\n"
        )
    };
    let instance = |name: &str, prototype: &str, x: f64| {
        format!(
            "def Xform \"{name}\" (\n    instanceable = true\n    references = </{prototype}>\n)\n{{\n    \
             double3 xformOp:translate = ({x}, 0, 0)\n    uniform token[] xformOpOrder = [\"xformOp:translate\"]\n}}\n"
        )
    };
    let text = [
        "#usda 1.0\n".to_string(),
        mesh("P1", "3", "0, 1, 2", "(0, 0, 0), (1, 0, 0), (0, 1, 0)"),
        mesh("P2", "4", "0, 1, 2, 3", "(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)"),
        instance("A", "P1", 0.0),
        instance("B", "P2", 2.0),
        instance("C", "P1", 4.0),
        instance("D", "P2", 6.0),
    ]
    .concat();
    let stage = write(dir.path(), "two.usda", &text);
    let kept = import(&stage, &ImportOptions::default()).unwrap();
    let record = kept.stage.as_ref().unwrap();
    let units: Vec<(&str, usize, usize)> = kept
        .instanced
        .iter()
        .map(|m| (record.prims[m.mesh_index as usize].as_str(), m.triangles.len(), m.placements.len()))
        .collect();
    assert_eq!(units, [("/A", 1, 2), ("/B", 2, 2)]);
    let flat = import(&stage, &ImportOptions { instancing: Instancing::Never, ..Default::default() }).unwrap();
    assert_eq!(flat.soup.triangles.len(), 6);
}
