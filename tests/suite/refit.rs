//! Refitting an owned file to moved triangles (`BvhFile::refit_triangles`): the file's own positions give its
//! bytes back; moved positions give, layout by layout, what an independent re-encoding of the same tree gives
//! (`reencode::reencode_everything`, written in the test from the format's rules), hits equal to a brute force
//! over the moved triangles on every kernel, and a file that verifies once rewritten; what a refit cannot take is
//! refused with the file unchanged.

use bvhc::loader::format::SectionKind;
use bvhc::loader::{BvhFile, Error, RebuildPolicy, RefitPositions};
use bvhc::options::{Overrides, Preset};

use crate::common::{assert_matches_brute_force, every_kernel, random_rays};
use crate::reencode::{assert_same_sections, breadth_first, reencoded, scramble_boxes, with_checksums};

type Triangle = [[f32; 3]; 3];

/// The teapot converted with the wide and GPU layouts, with or without split references.
fn teapot(dir: &std::path::Path, splits: bool) -> BvhFile {
    let teapot = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let output = dir.join(if splits { "split.bvh" } else { "teapot.bvh" });
    let budget = splits.then_some(1.0);
    let overrides =
        Overrides { splits: Some(splits), split_budget: budget, gpu_layout: Some(true), ..Overrides::default() };
    bvhc::Conversion::new(teapot, &output).preset(Preset::Balanced).overrides(overrides).run().unwrap();
    BvhFile::read(&output).unwrap()
}

fn positions(file: &BvhFile) -> Vec<Triangle> {
    file.view().triangles().iter().map(|t| t.vertices).collect()
}

/// A smooth deformation: a bend about the y axis growing with height, and a twist.
fn bent(positions: &[Triangle]) -> Vec<Triangle> {
    let bend = |[x, y, z]: [f32; 3]| {
        let a = 0.15 * y;
        [x * a.cos() - z * a.sin() + 0.3 * y * y, y * 1.1, x * a.sin() + z * a.cos()]
    };
    positions.iter().map(|t| t.map(bend)).collect()
}

#[test]
fn a_refit_to_the_files_own_positions_gives_its_bytes_back() {
    let dir = tempfile::tempdir().unwrap();
    let original = teapot(dir.path(), false);
    let mut file = BvhFile::from_bytes(original.as_bytes()).unwrap();
    // Scramble every box, packet lane and GPU triangle first, so that each layout's refit, not the old bytes,
    // makes the result.
    {
        let mut edit = file.edit().unwrap();
        scramble_boxes(&mut edit);
        for packet in edit.triangle_packets.as_deref_mut().unwrap() {
            for lane in (0..4).filter(|&l| packet.triangle_index[l] != u32::MAX) {
                packet.vertices[1][2][lane] += 1.0;
            }
        }
        edit.gpu_nodes.as_deref_mut().unwrap().iter_mut().for_each(|n| n.quantized_max = [[0; 8]; 3]);
        edit.gpu_triangles.as_deref_mut().unwrap().iter_mut().for_each(|t| t.vertices[0][0] += 1.0);
    }
    assert_ne!(file.as_bytes(), original.as_bytes());
    file.refit_triangles(&positions(&original)).unwrap();
    assert_same_sections(&file, &original, "refit to its own positions");
    // A refit leaves the checksums as they were (the scrambled bytes'); with them recomputed the file verifies.
    let stale = file.view().verify().expect_err("the checksums describe the scrambled bytes");
    assert!(stale.to_string().contains("checksum"), "{stale}");
    with_checksums(&file).view().verify().unwrap();
}

#[test]
fn a_refit_to_moved_triangles_equals_a_re_encoding_and_traces_them_on_every_kernel() {
    let dir = tempfile::tempdir().unwrap();
    let original = teapot(dir.path(), false);
    let moved = bent(&positions(&original));
    let mut refit = BvhFile::from_bytes(original.as_bytes()).unwrap();
    refit.refit_triangles(&moved).unwrap();
    // The same tree re-encoded by the test's own reading of the format's rules.
    let expected = reencoded(&original, &moved);
    assert_eq!(with_checksums(&refit).as_bytes(), expected.as_bytes(), "the refit and the test's re-encoding");
    assert_ne!(refit.as_bytes(), original.as_bytes());
    // Every layout holds its geometry (the rules on boxes and lanes), and the stated costs are stale until the
    // file is rewritten.
    let stale = with_checksums(&refit).view().verify().expect_err("the metadata's costs describe the old positions");
    assert!(stale.to_string().contains("cost"), "{stale}");
    let shipped = refit.rewritten().unwrap();
    shipped.view().verify().unwrap();
    // The hits are the moved triangles', on the binary kernel and the wide one on every path.
    let box_min = moved.iter().flatten().fold([f32::INFINITY; 3], |m, v| std::array::from_fn(|a| m[a].min(v[a])));
    let box_max = moved.iter().flatten().fold([f32::NEG_INFINITY; 3], |m, v| std::array::from_fn(|a| m[a].max(v[a])));
    let extent = (0..3).map(|a| box_max[a] - box_min[a]).fold(0.0, f32::max);
    let centre: [f32; 3] = std::array::from_fn(|a| 0.5 * (box_min[a] + box_max[a]));
    let rays: Vec<_> = random_rays(77, 2000, extent)
        .into_iter()
        .map(|mut r| {
            r.origin = std::array::from_fn(|a| r.origin[a] + centre[a]);
            r
        })
        .collect();
    let ids: Vec<u32> = (0..moved.len() as u32).collect();
    for file in [&refit, &shipped] {
        let view = file.view();
        for tracer in every_kernel(&view) {
            let hits = assert_matches_brute_force(&tracer, &moved, &rays, &ids);
            assert!(hits > 100, "{hits} of {} rays hit the bent teapot", rays.len());
        }
    }
}

#[test]
fn a_file_with_split_references_refits_each_reference_to_its_whole_triangle() {
    let dir = tempfile::tempdir().unwrap();
    let original = teapot(dir.path(), true);
    assert!(original.view().has_split_references());
    let ids: Vec<u32> = (0..original.view().triangles().len() as u32).collect();
    // At its own positions: every layout's boxes now hold whole triangles, a looser tree than the pieces'.
    let mut own = BvhFile::from_bytes(original.as_bytes()).unwrap();
    let report = own.refit_triangles(&positions(&original)).unwrap();
    assert!(report.cost_ratio() > 1.0, "{report:?}");
    own.rewritten().unwrap().view().verify().unwrap();
    // Bent: a function of each vertex, so a triangle's references move alike; the hits are the bent triangles'.
    let moved = bent(&positions(&original));
    let mut refit = BvhFile::from_bytes(original.as_bytes()).unwrap();
    refit.refit(RefitPositions::Triangles(&moved), 2).unwrap();
    let shipped = refit.rewritten().unwrap();
    shipped.view().verify().unwrap();
    let rays = random_rays(79, 2000, 4.0);
    for tracer in every_kernel(&shipped.view()) {
        assert!(assert_matches_brute_force(&tracer, &moved, &rays, &ids) > 100);
    }
}

#[test]
fn what_a_refit_cannot_take_is_refused_with_the_file_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = teapot(dir.path(), false);
    let before = file.as_bytes().to_vec();
    let good = positions(&file);
    let refused = |file: &mut BvhFile, positions: &[Triangle]| match file.refit_triangles(positions) {
        Err(Error::Refit(why)) => why,
        other => panic!("refused as a refit error, got {other:?}"),
    };
    let why = refused(&mut file, &good[1..]);
    assert!(why.contains(&format!("{} positions for {} triangle records", good.len() - 1, good.len())), "{why}");
    let mut nan = good.clone();
    nan[17][2][1] = f32::NAN;
    assert!(refused(&mut file, &nan).contains("triangle record 17"));
    let mut infinite = good.clone();
    infinite[3][0][0] = f32::INFINITY;
    assert!(refused(&mut file, &infinite).contains("triangle record 3"));
    assert_eq!(file.as_bytes(), &before[..], "a refused refit leaves the file as it was");
    // Split references (the golden file of section 12's fourth dump): the references of one triangle must move
    // alike, and without ids they cannot be told apart.
    let golden = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/golden");
    let mut split = BvhFile::read(golden.join("split-v1.1.bvh")).unwrap();
    assert!(split.view().has_split_references());
    let ids = split.view().triangle_ids().unwrap().to_vec();
    let (a, b) = (0..ids.len())
        .flat_map(|a| (a + 1..ids.len()).map(move |b| (a, b)))
        .find(|&(a, b)| ids[a] == ids[b])
        .expect("a split triangle");
    let mut apart = positions(&split);
    apart[b][0][0] += 0.25;
    let why = refused(&mut split, &apart);
    assert!(why.contains(&format!("triangle records {a} and {b} are references of one triangle")), "{why}");
    let output = dir.path().join("split-no-ids.bvh");
    let teapot_obj = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let overrides =
        Overrides { splits: Some(true), split_budget: Some(1.0), write_ids: Some(false), ..Overrides::default() };
    bvhc::Conversion::new(teapot_obj, &output).overrides(overrides).run().unwrap();
    let mut no_ids = BvhFile::read(&output).unwrap();
    assert!(no_ids.view().has_split_references());
    let no_ids_positions = positions(&no_ids);
    assert!(refused(&mut no_ids, &no_ids_positions).contains("no triangle ids"));
    let error = file.refit_triangles(&good[..3]).unwrap_err();
    assert!(error.to_string().starts_with("cannot refit .bvh file: "), "{error}");
}

/// A wavy grid of `2 * n * n` triangles as an OBJ (vertices in rows), for files large enough that a refit
/// spreads its passes over threads.
fn grid_obj(dir: &std::path::Path, n: usize) -> (std::path::PathBuf, Vec<[f32; 3]>) {
    let mut vertices = Vec::with_capacity((n + 1) * (n + 1));
    for i in 0..=n {
        for j in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            vertices.push([x, 0.05 * (9.0 * x).sin() * (7.0 * z).cos(), z]);
        }
    }
    let mut text = String::new();
    for v in &vertices {
        text.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
    }
    for i in 0..n {
        for j in 0..n {
            let a = i * (n + 1) + j + 1;
            let (b, c, d) = (a + 1, a + n + 1, a + n + 2);
            text.push_str(&format!("f {a} {c} {b}\nf {b} {c} {d}\n"));
        }
    }
    let path = dir.join("grid.obj");
    std::fs::write(&path, text).unwrap();
    (path, vertices)
}

/// The grid bent about its middle: a vertex function, so per-vertex and per-record positions agree.
fn bend_vertex([x, y, z]: [f32; 3]) -> [f32; 3] {
    let a = 0.8 * (x - 0.5);
    [0.5 + (x - 0.5) * a.cos() - y * a.sin(), (x - 0.5) * a.sin() + y * a.cos() + 0.3 * z * z, z]
}

#[test]
fn a_refit_gives_the_same_bytes_on_any_thread_count_per_record_or_per_source_vertex() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, vertices) = grid_obj(dir.path(), 450);
    let output = dir.path().join("grid.bvh");
    let overrides = Overrides { splits: Some(false), gpu_layout: Some(true), ..Overrides::default() };
    bvhc::Conversion::new(&obj, &output).preset(Preset::Fast).overrides(overrides).run().unwrap();
    let original = BvhFile::read(&output).unwrap();
    let moved: Vec<Triangle> = positions(&original).iter().map(|t| t.map(bend_vertex)).collect();
    let mut one = BvhFile::from_bytes(original.as_bytes()).unwrap();
    let report = one.refit(RefitPositions::Triangles(&moved), 1).unwrap();
    let expected = reencoded(&original, &moved);
    assert!(with_checksums(&one).as_bytes() == expected.as_bytes(), "one thread against the re-encoding");
    for threads in [0, 2, 3, 8] {
        let mut file = BvhFile::from_bytes(original.as_bytes()).unwrap();
        let again = file.refit(RefitPositions::Triangles(&moved), threads).unwrap();
        assert!(file.as_bytes() == one.as_bytes(), "{threads} threads: other bytes");
        // The costs are summed per subtree, the same subtrees on any thread count.
        assert_eq!(again, report, "{threads} threads");
    }
    // The same move given per source vertex (the OBJ's `v` records, one source range).
    let bent_vertices: Vec<[f32; 3]> = vertices.iter().map(|&v| bend_vertex(v)).collect();
    for threads in [1, 2] {
        let mut file = BvhFile::from_bytes(original.as_bytes()).unwrap();
        file.refit(RefitPositions::SourceVertices(&[Some(&bent_vertices)]), threads).unwrap();
        assert!(file.as_bytes() == one.as_bytes(), "per source vertex, {threads} threads: other bytes");
        // `None` leaves the range where it is.
        file.refit(RefitPositions::SourceVertices(&[None]), threads).unwrap();
        assert!(file.as_bytes() == one.as_bytes(), "a range left as it is: other bytes");
    }
    one.view().verify().expect_err("stale costs until rewritten");
    one.rewritten().unwrap().view().verify().unwrap();
}

#[test]
fn a_file_in_another_layout_refits_as_a_re_encoding_says() {
    // The grid's trees laid out breadth first: valid files (children after parents, V14 and V29) that another
    // writer might produce, whose subtrees are not runs of nodes, so the refit takes its whole-tree passes.
    let dir = tempfile::tempdir().unwrap();
    let (obj, _) = grid_obj(dir.path(), 450);
    let output = dir.path().join("grid.bvh");
    let overrides = Overrides { splits: Some(false), gpu_layout: Some(true), ..Overrides::default() };
    bvhc::Conversion::new(&obj, &output).preset(Preset::Fast).overrides(overrides).run().unwrap();
    let original = BvhFile::read(&output).unwrap();
    let mut relaid = BvhFile::from_bytes(original.as_bytes()).unwrap();
    breadth_first(&mut relaid);
    assert_ne!(relaid.view().nodes(), original.view().nodes());
    relaid.view().verify().unwrap();
    let moved: Vec<Triangle> = positions(&original).iter().map(|t| t.map(bend_vertex)).collect();
    let expected = reencoded(&relaid, &moved);
    let mut in_layout = BvhFile::from_bytes(original.as_bytes()).unwrap();
    let report = in_layout.refit(RefitPositions::Triangles(&moved), 2).unwrap();
    for threads in [1, 2] {
        let mut file = BvhFile::from_bytes(relaid.as_bytes()).unwrap();
        let again = file.refit(RefitPositions::Triangles(&moved), threads).unwrap();
        assert!(with_checksums(&file).as_bytes() == expected.as_bytes(), "{threads} threads: other bytes");
        // The same trees' costs, summed in another order.
        for (a, b) in [(again.cost, report.cost), (again.wide_cost, report.wide_cost)] {
            let (a, b) = (a.unwrap(), b.unwrap());
            assert!((a - b).abs() <= 1e-12 * b, "{threads} threads: {a} vs {b}");
        }
    }
}

#[test]
fn the_report_compares_the_refit_trees_cost_with_the_files_own() {
    let dir = tempfile::tempdir().unwrap();
    let original = teapot(dir.path(), false);
    let mut file = BvhFile::from_bytes(original.as_bytes()).unwrap();
    let own = file.refit_triangles(&positions(&original)).unwrap();
    assert!((own.cost_ratio() - 1.0).abs() < 1e-9, "{own:?}");
    assert!(own.wide_cost.is_some() && own.cost.is_some(), "{own:?}");
    assert!(!RebuildPolicy::DEFAULT.should_rebuild(&own));
    // Every vertex thrown about by a hash of its position (so shared corners stay shared): the tree's boxes
    // grow and overlap, the cost ratio grows, and a policy reads it.
    let throw = |[x, y, z]: [f32; 3]| {
        let h = (x.to_bits() ^ y.to_bits().rotate_left(11) ^ z.to_bits().rotate_left(22)).wrapping_mul(0x9E37_79B9);
        let offset = |k: u32| ((h.rotate_left(k) & 0xFFFF) as f32 / 65535.0 - 0.5) * 3.0;
        [x + offset(0), y + offset(10), z + offset(20)]
    };
    let sheared: Vec<Triangle> = positions(&original).iter().map(|t| t.map(throw)).collect();
    let report = file.refit_triangles(&sheared).unwrap();
    assert!(report.cost_ratio() > 1.5, "{report:?}");
    assert!(RebuildPolicy::DEFAULT.should_rebuild(&report));
    assert!(!RebuildPolicy { max_cost_ratio: report.cost_ratio() }.should_rebuild(&report));
    // The rewritten file states the refit tree's costs: a refit to its own positions then reads 1.
    let mut shipped = file.rewritten().unwrap();
    let again = shipped.refit_triangles(&sheared).unwrap();
    assert!((again.cost_ratio() - 1.0).abs() < 1e-9, "{again:?}");
}

#[test]
fn positions_per_source_vertex_that_do_not_fit_are_refused_naming_what() {
    let dir = tempfile::tempdir().unwrap();
    let (obj, vertices) = grid_obj(dir.path(), 4);
    let output = dir.path().join("small.bvh");
    let overrides = Overrides { splits: Some(false), ..Overrides::default() };
    bvhc::Conversion::new(&obj, &output).overrides(overrides).run().unwrap();
    let mut file = BvhFile::read(&output).unwrap();
    let before = file.as_bytes().to_vec();
    let refused = |file: &mut BvhFile, positions: RefitPositions<'_>| match file.refit(positions, 2) {
        Err(Error::Refit(why)) => why,
        other => panic!("refused as a refit error, got {other:?}"),
    };
    let why = refused(&mut file, RefitPositions::SourceVertices(&[]));
    assert!(why.contains("positions for 0 source ranges, but the file has 1"), "{why}");
    let why = refused(&mut file, RefitPositions::SourceVertices(&[Some(&vertices[..10])]));
    assert!(why.contains("source range 0") && why.contains("10 positions were given"), "{why}");
    let mut nan = vertices.clone();
    nan[7][1] = f32::NAN;
    let why = refused(&mut file, RefitPositions::SourceVertices(&[Some(&nan)]));
    assert!(why.contains("source range 0, vertex 7"), "{why}");
    assert_eq!(file.as_bytes(), &before[..], "a refused refit leaves the file as it was");
    // A file written without source vertices cannot take them.
    let bare = dir.path().join("bare.bvh");
    let overrides = Overrides { splits: Some(false), write_source_vertices: Some(false), ..Overrides::default() };
    bvhc::Conversion::new(&obj, &bare).overrides(overrides).run().unwrap();
    let mut bare = BvhFile::read(&bare).unwrap();
    let why = refused(&mut bare, RefitPositions::SourceVertices(&[Some(&vertices)]));
    assert!(why.contains("source_vertices section"), "{why}");
}

/// A glTF of two meshes of long crossing slivers (which split references cut), the second with a morph target
/// (geometry meant to deform; the target's deltas are zero).
fn slivers_gltf(dir: &std::path::Path) -> std::path::PathBuf {
    let mut positions: Vec<f32> = Vec::new();
    for k in 0..48 {
        let a = k as f32 * 0.131;
        positions.extend([0.0, 0.0, 0.0]);
        positions.extend([10.0 * a.cos(), 10.0 * a.sin(), 0.0]);
        positions.extend([10.0 * (a + 0.02).cos(), 10.0 * (a + 0.02).sin(), 0.05]);
    }
    let count = positions.len() / 3;
    let mut bin: Vec<u8> = positions.iter().flat_map(|c| c.to_le_bytes()).collect();
    bin.extend(std::iter::repeat_n(0u8, count * 12));
    let (lo, hi) = ([-10.0, -10.0, 0.0], [10.0, 10.0, 0.05]);
    let gltf = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"mesh": 1, "translation": [0.0, 0.0, 0.5]}],
        "meshes": [
            {"primitives": [{"attributes": {"POSITION": 0}}]},
            {"primitives": [{"attributes": {"POSITION": 0}, "targets": [{"POSITION": 1}]}], "weights": [0.0]}
        ],
        "buffers": [{"uri": "slivers.bin", "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": count * 12},
            {"buffer": 0, "byteOffset": count * 12, "byteLength": count * 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": count, "type": "VEC3", "min": lo, "max": hi},
            {"bufferView": 1, "componentType": 5126, "count": count, "type": "VEC3", "min": [0, 0, 0], "max": [0, 0, 0]}
        ]
    });
    std::fs::write(dir.join("slivers.bin"), bin).unwrap();
    let path = dir.join("slivers.gltf");
    std::fs::write(&path, gltf.to_string()).unwrap();
    path
}

/// Per mesh of the slivers, whether some triangle of it has several records (split references).
fn split_meshes(file: &BvhFile) -> [bool; 2] {
    let view = file.view();
    let (ids, ranges) = (view.triangle_ids().unwrap(), view.source_table().unwrap());
    let mut seen = std::collections::HashSet::new();
    let mut split = [false; 2];
    for &id in ids {
        if !seen.insert(id) {
            let range = ranges.iter().find(|r| id - r.first_source_triangle < r.source_triangle_count).unwrap();
            split[range.mesh_index as usize] = true;
        }
    }
    split
}

#[test]
fn no_splits_deforming_leaves_the_geometry_meant_to_deform_whole_and_the_rest_cut() {
    let dir = tempfile::tempdir().unwrap();
    let input = slivers_gltf(dir.path());
    let convert = |name: &str, deforming: Option<bool>| {
        let output = dir.path().join(name);
        let overrides = Overrides {
            split_budget: Some(1.0),
            split_triangles: Some(bvhc::options::SplitTriangles::Any),
            splits_deforming: deforming,
            ..Overrides::default()
        };
        bvhc::Conversion::new(&input, &output).overrides(overrides).run().unwrap();
        BvhFile::read(&output).unwrap()
    };
    // By default both meshes are cut; with the option, only the static one.
    assert_eq!(split_meshes(&convert("default.bvh", None)), [true, true]);
    let kept = convert("kept.bvh", Some(false));
    assert_eq!(split_meshes(&kept), [true, false]);
    kept.view().verify().unwrap();
    let metadata: serde_json::Value = serde_json::from_str(kept.view().metadata_str().unwrap().unwrap()).unwrap();
    assert_eq!(metadata["build"]["splits"]["deforming"], false);
    crate::common::assert_metadata_matches_schema(&kept);
    // The morphed mesh moves per source vertex, the static one stays: a refit of the file's own split pieces
    // and the moved whole triangles, which verifies and traces.
    let count = 48 * 3;
    let ranges = kept.view().source_table().unwrap().to_vec();
    let lifted: Vec<[f32; 3]> = (0..count)
        .map(|v| {
            let (k, corner) = ((v / 3) as f32 * 0.131, v % 3);
            let a = k + if corner == 2 { 0.02 } else { 0.0 };
            let r = if corner == 0 { 0.0 } else { 10.0 };
            [r * a.cos(), r * a.sin(), 0.5 + if corner == 2 { 0.05 } else { 0.0 } + 0.3]
        })
        .collect();
    let positions: Vec<Option<&[[f32; 3]]>> =
        ranges.iter().map(|r| (r.mesh_index == 1).then_some(&lifted[..])).collect();
    let mut refit = BvhFile::from_bytes(kept.as_bytes()).unwrap();
    refit.refit(RefitPositions::SourceVertices(&positions), 2).unwrap();
    refit.rewritten().unwrap().view().verify().unwrap();
}

#[test]
fn a_refit_of_corrupted_bytes_never_panics() {
    // Files that open (the structural rules) but break the tree rules: child and leaf indices, packet lanes and
    // GPU metas scribbled over. A refit may refuse or write nonsense boxes; it must neither panic nor hang.
    let dir = tempfile::tempdir().unwrap();
    let original = teapot(dir.path(), false);
    let moved = bent(&positions(&original));
    let kinds = [SectionKind::Nodes, SectionKind::WideNodes, SectionKind::TrianglePackets, SectionKind::GpuNodes];
    for (round, mut file) in crate::common::scribbled_copies(&original, &kinds, 300, 40, 46) {
        let _ = file.refit(RefitPositions::Triangles(&moved), 1 + round % 3);
    }
}

/// `rewritten_recording` (what `bvhc refit` writes its `refit` key with): the member set once and last, any
/// earlier one of that name gone, the costs recomputed as `rewritten` does, every other member kept; a file
/// without metadata gets an object of that member alone; a value that is not one JSON value, or a name JSON
/// cannot hold unescaped, refused with nothing built.
#[test]
fn a_recorded_member_replaces_its_namesake_and_the_rest_is_rewritten() {
    let dir = tempfile::tempdir().unwrap();
    let file = teapot(dir.path(), false);
    let mut refit = BvhFile::from_bytes(file.as_bytes()).unwrap();
    refit.refit(RefitPositions::Triangles(&bent(&positions(&file))), 1).unwrap();
    let once = refit.rewritten_recording("refit", Some(r#"{"inputs":[]}"#)).unwrap();
    let twice = once.rewritten_recording("refit", Some(r#" {"inputs":[{"file_name":"a.gltf","content_hash":"x"}]} "#));
    let twice = twice.unwrap();
    let text = |f: &BvhFile| f.view().metadata_str().unwrap().unwrap().to_string();
    assert!(text(&twice).ends_with(r#","refit":{"inputs":[{"file_name":"a.gltf","content_hash":"x"}]}}"#));
    assert_eq!(text(&twice).matches(r#""refit""#).count(), 1);
    let plain = refit.rewritten().unwrap();
    let without = text(&twice).replace(r#","refit":{"inputs":[{"file_name":"a.gltf","content_hash":"x"}]}"#, "");
    assert_eq!(without, text(&plain), "the rest is what rewritten writes, costs recomputed");
    let removed = twice.rewritten_recording("refit", None).unwrap();
    assert!(removed.as_bytes() == plain.as_bytes(), "removing the member gives rewritten's bytes");
    twice.view().verify().unwrap();
    assert_eq!(twice.view().triangles(), plain.view().triangles());

    let bare = bvhc::loader::write::BvhWriter::from_view(&file.view()).metadata("{ }").build();
    let recorded = bare.unwrap().rewritten_recording("note", Some("[1, 2]")).unwrap();
    assert_eq!(text(&recorded), r#"{"note":[1, 2] }"#);
    for (name, value) in [("refit", "{"), ("refit", "1 2"), ("refit", ""), ("a\"b", "1"), ("a\\b", "1")] {
        let error = refit.rewritten_recording(name, Some(value)).unwrap_err();
        assert!(matches!(error, Error::Unwritable(_)), "{name} {value}: {error}");
        assert!(error.to_string().contains("metadata member"), "{error}");
    }
}
