//! Shared helpers: deterministic random scenes and rays, the build -> pack -> write path, and the brute-force
//! oracle every traversal test compares against.

use bvhc_loader::Trace;
use std::path::PathBuf;

use bvhc::builders::build_binned_sah;
use bvhc::loader::{BvhFile, Hit, Ray, Tracer, format::SourceRange, ray::PreparedRay, write::BvhWriter};
use bvhc::pack::{PackedTree, pack};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;

pub type Triangle = [[f32; 3]; 3];

pub fn rng(seed: u64) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(seed)
}

pub fn random_point(rng: &mut Pcg64Mcg, extent: f32) -> [f32; 3] {
    std::array::from_fn(|_| rng.random_range(-extent..extent))
}

/// `count` random triangles: small ones scattered in a cube of half-size `extent`, plus a few large ones.
pub fn random_triangles(seed: u64, count: usize, extent: f32) -> Vec<Triangle> {
    let mut rng = rng(seed);
    (0..count)
        .map(|i| {
            let center = random_point(&mut rng, extent);
            let size = if i % 50 == 0 { extent } else { extent * 0.05 };
            std::array::from_fn(|_| {
                let d = random_point(&mut rng, size);
                [center[0] + d[0], center[1] + d[1], center[2] + d[2]]
            })
        })
        .collect()
}

/// Rays from random points in a box of half-size `extent` towards random points in it, some with exact zero
/// direction components.
pub fn random_rays(seed: u64, count: usize, extent: f32) -> Vec<Ray> {
    let mut rng = rng(seed);
    (0..count)
        .map(|i| {
            let origin = random_point(&mut rng, extent * 1.5);
            let target = random_point(&mut rng, extent);
            let mut direction: [f32; 3] = std::array::from_fn(|a| target[a] - origin[a]);
            match i % 7 {
                0 => direction[i % 3] = 0.0,
                1 => direction[(i + 1) % 3] = -0.0,
                2 => {
                    direction[i % 3] = 0.0;
                    direction[(i + 1) % 3] = -0.0;
                }
                _ => {}
            }
            Ray::new(origin, direction)
        })
        .collect()
}

/// Builds and packs a binned SAH tree with at most `max_leaf_size` triangles per leaf.
pub fn packed_tree(triangles: &[Triangle], max_leaf_size: usize) -> PackedTree {
    pack(&build_binned_sah(triangles, max_leaf_size), triangles).expect("memory for the packed tree")
}

/// One source range covering ids `0..triangle_count`.
pub fn single_source_range(triangle_count: usize) -> Vec<SourceRange> {
    vec![SourceRange {
        first_source_triangle: 0,
        source_triangle_count: triangle_count.max(1) as u32,
        file_index: 0,
        node_index: u32::MAX,
        mesh_index: 0,
        primitive_index: u32::MAX,
        instance_index: u32::MAX,
        reserved: 0,
    }]
}

pub const METADATA: &str = r#"{"generator":"bvhc tests","format_version":"1.0"}"#;

/// The full file (ids, source table, metadata) of a packed tree.
pub fn write_file(tree: &PackedTree) -> BvhFile {
    let ranges = single_source_range(tree.triangles.len());
    let writer = BvhWriter::new(&tree.nodes, &tree.triangles).triangle_ids(&tree.triangle_ids).metadata(METADATA);
    let writer = if tree.triangles.is_empty() { writer } else { writer.source_table(&ranges) };
    writer.build().expect("a packed tree always writes")
}

/// Metadata for test files of version 1.1 (V28).
pub const METADATA_1_1: &str = r#"{"generator":"bvhc tests","format_version":"1.1"}"#;

/// A version 1.1 file over `triangles`: the binary tree of [`packed_tree`] (at most `max_leaf_size` triangles a
/// leaf) with ids, source table and metadata, and the wide sections collapsed (default costs) from the binned
/// SAH tree with one triangle per leaf, as the conversion does.
pub fn write_wide_file(triangles: &[Triangle], max_leaf_size: usize) -> BvhFile {
    let tree = packed_tree(triangles, max_leaf_size);
    let wide = wide_sections_for(&tree, triangles);
    let ranges = single_source_range(tree.triangles.len());
    let writer = BvhWriter::new(&tree.nodes, &tree.triangles)
        .triangle_ids(&tree.triangle_ids)
        .metadata(METADATA_1_1)
        .wide(wide.nodes(), wide.packets());
    let writer = if tree.triangles.is_empty() { writer } else { writer.source_table(&ranges) };
    writer.build().expect("a packed tree with its wide sections always writes")
}

/// The wide sections over a packed tree's triangles section (`tree.triangle_ids` are indices into `triangles`).
pub fn wide_sections_for(tree: &PackedTree, triangles: &[Triangle]) -> bvhc::loader::wide::WideBvh {
    let opt = bvhc::optimize::OptTree::from_build_tree(&build_binned_sah(triangles, 1), triangles);
    let collapsed = bvhc::layout::collapse(&opt, &bvhc::layout::WideCosts::default());
    let file_index_of = tree.file_index_of(triangles.len()).expect("memory");
    bvhc::pack::pack_wide(&collapsed, &tree.triangles, &mut |t| file_index_of.get(t as usize).copied(), false)
        .expect("a collapsed tree packs")
}

/// Overwrites the last used lane of the last packet with packet 0's lane 0 (index and vertices): a triangle
/// then sits in two lanes and the one it replaced in none.
pub fn repeat_first_lane_in_last(packets: &mut [bvhc::loader::format::TrianglePacket4]) {
    let (index, triangle) = (packets[0].triangle_index[0], packets[0].triangle(0));
    let last = packets.len() - 1;
    let lane = packets[last].used_lanes() - 1;
    packets[last].triangle_index[lane] = index;
    for vertex in 0..3 {
        for axis in 0..3 {
            packets[last].vertices[vertex][axis][lane] = triangle.vertices[vertex][axis];
        }
    }
}

/// The closest hit by testing every triangle with the kernel's own watertight test.
pub fn brute_force_closest(triangles: &[Triangle], ray: &Ray) -> Option<(f32, usize)> {
    let prepared = PreparedRay::new(ray);
    let mut best: Option<(f32, usize)> = None;
    for (i, vertices) in triangles.iter().enumerate() {
        let t_max = best.map_or(ray.t_max, |b| b.0);
        let triangle = bvhc::loader::format::PackedTriangle { vertices: *vertices };
        if let Some(hit) = prepared.intersect_triangle(&triangle, t_max)
            && best.is_none_or(|b| hit.t < b.0)
        {
            best = Some((hit.t, i));
        }
    }
    best
}

/// Asserts that the tracer's closest hit equals brute force over `source` (the input triangles): the same t,
/// and a triangle with that t (ties at shared edges may pick either); any-hit agrees too.
pub fn assert_matches_brute_force(tracer: &Tracer<'_>, source: &[Triangle], rays: &[Ray], ids: &[u32]) -> usize {
    let mut hits = 0;
    for (r, ray) in rays.iter().enumerate() {
        let expected = brute_force_closest(source, ray);
        let got: Option<Hit> = tracer.closest_hit(ray);
        match (expected, got) {
            (None, None) => {}
            (Some((t, _)), Some(hit)) => {
                hits += 1;
                assert_eq!(hit.t, t, "ray {r} {ray:?}: t differs");
                let source_index = ids[hit.triangle_index as usize] as usize;
                let again = brute_force_closest(&source[source_index..=source_index], ray);
                assert_eq!(again.map(|h| h.0), Some(t), "ray {r}: reported triangle is not hit at t");
            }
            (e, g) => panic!("ray {r} {ray:?}: brute force {e:?}, traversal {g:?}"),
        }
        assert_eq!(tracer.any_hit(ray), expected.is_some(), "ray {r}: any-hit disagrees");
    }
    hits
}

/// The shared scenes folder: `BVHC_SCENES`, else `../shared/scenes` beside the repository.
pub fn scenes_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("BVHC_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"));
    dir.is_dir().then_some(dir)
}

/// A scene file from the shared folder, or `None` (with a note on stderr) when it is not on this machine.
pub fn scene(relative: &str) -> Option<PathBuf> {
    let path = scenes_dir().map(|d| d.join(relative)).filter(|p| p.is_file());
    if path.is_none() {
        crate::skips::skipped(
            crate::skips::Needs::Scenes,
            format!("scene {relative} (set BVHC_SCENES to the shared scenes folder)"),
        );
    }
    path
}

/// An icosahedron subdivided `levels` times and pushed onto the unit sphere, in f64: a closed mesh whose
/// vertices are shared between triangles.
pub fn unit_icosphere(levels: usize) -> (Vec<[f64; 3]>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut f: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut cache = std::collections::HashMap::new();
        let mut mid = |a: usize, b: usize, v: &mut Vec<[f64; 3]>| {
            *cache.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(std::array::from_fn(|k| (v[a][k] + v[b][k]) / 2.0));
                v.len() - 1
            })
        };
        f = f
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (mid(a, b, &mut v), mid(b, c, &mut v), mid(c, a, &mut v));
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    for p in &mut v {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        *p = p.map(|c| c / l);
    }
    (v, f)
}

/// The metadata JSON Schema of `format-spec/`, compiled once.
fn metadata_schema() -> &'static jsonschema::Validator {
    static SCHEMA: std::sync::OnceLock<jsonschema::Validator> = std::sync::OnceLock::new();
    SCHEMA.get_or_init(|| {
        let text = include_str!("../../format-spec/metadata.schema.json");
        let schema: serde_json::Value = serde_json::from_str(text).expect("the schema is JSON");
        jsonschema::validator_for(&schema).expect("the schema is a valid JSON Schema")
    })
}

/// Asserts that a written file's metadata (when it has one) validates against `format-spec/metadata.schema.json`;
/// returns the metadata.
pub fn assert_metadata_matches_schema(file: &BvhFile) -> serde_json::Value {
    let Some(text) = file.view().metadata_str() else { return serde_json::Value::Null };
    let metadata: serde_json::Value = serde_json::from_str(text.expect("UTF-8")).expect("metadata is JSON");
    let errors: Vec<String> =
        metadata_schema().iter_errors(&metadata).map(|e| format!("{e} at {}", e.instance_path())).collect();
    assert!(errors.is_empty(), "metadata breaks the schema: {errors:?}\n{metadata:#}");
    metadata
}

/// The 8-wide BVH of `triangles` (binned SAH, one triangle per leaf, collapsed with the default costs), with
/// triangle indices into `triangles`.
pub fn wide_bvh(triangles: &[Triangle]) -> bvhc::loader::wide::WideBvh {
    let tree = bvhc::optimize::OptTree::from_build_tree(&build_binned_sah(triangles, 1), triangles);
    wide_bvh_of(&tree, triangles)
}

/// [`wide_bvh`] from a given binary optimizer tree.
pub fn wide_bvh_of(tree: &bvhc::optimize::OptTree, triangles: &[Triangle]) -> bvhc::loader::wide::WideBvh {
    let wide = bvhc::layout::collapse(tree, &bvhc::layout::WideCosts::default());
    let packed: Vec<bvhc::loader::format::PackedTriangle> =
        triangles.iter().map(|&vertices| bvhc::loader::format::PackedTriangle { vertices }).collect();
    bvhc::pack::pack_wide(&wide, &packed, &mut Some, false).expect("a collapsed tree packs")
}

/// Every kernel a view can trace with: the binary one, then the wide one on each path this machine runs
/// (files with wide sections only).
pub fn every_kernel<'a>(view: &bvhc::loader::BvhView<'a>) -> Vec<Tracer<'a>> {
    let binary = view.binary_tracer();
    let wide = kernel_paths().into_iter().filter_map(|path| view.wide_tracer(path)).map(|w| binary.with_wide(w));
    std::iter::once(binary).chain(wide).collect()
}

/// The wide kernel paths this machine runs (the others are reported as skipped).
pub fn kernel_paths() -> Vec<bvhc::loader::KernelPath> {
    use bvhc::loader::KernelPath;
    [KernelPath::Portable, KernelPath::Avx2]
        .into_iter()
        .filter(|p| {
            let supported = p.is_supported();
            if !supported {
                crate::skips::skipped(
                    crate::skips::Needs::Machine,
                    format!("part: kernel path {p:?} (not supported here)"),
                );
            }
            supported
        })
        .collect()
}

/// `f` run in a rayon pool of `threads` threads (for checks that results do not depend on the thread count).
pub fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap().install(f)
}

/// `rounds` copies of `file` that still open (the structural rules), each with up to `max_bytes` random bytes
/// written over one of the sections of `kinds` (round by round in turn): for the checks that code reading a file
/// that breaks the tree rules never panics.
pub fn scribbled_copies(
    file: &BvhFile,
    kinds: &[bvhc::loader::format::SectionKind],
    rounds: usize,
    max_bytes: usize,
    seed: u64,
) -> Vec<(usize, BvhFile)> {
    let sections: Vec<(usize, usize)> = file
        .view()
        .sections()
        .filter(|s| s.kind.is_some_and(|k| kinds.contains(&k)))
        .map(|s| (s.entry.section_byte_offset as usize, s.entry.section_byte_len as usize))
        .collect();
    let mut rng = rng(seed);
    let mut copies = Vec::new();
    for round in 0..rounds {
        let mut bytes = file.as_bytes().to_vec();
        let (offset, len) = sections[round % sections.len()];
        for _ in 0..rng.random_range(1..max_bytes) {
            bytes[offset + rng.random_range(0..len)] = rng.random();
        }
        if let Ok(copy) = BvhFile::from_bytes(&bytes) {
            copies.push((round, copy));
        }
    }
    copies
}
