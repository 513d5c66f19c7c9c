//! glTF placement against an independent oracle: the gltf crate's own validated reader decodes each primitive,
//! the test accumulates node transforms in f64, and every imported triangle must equal its local triangle
//! placed in world space, in the source's winding, reversed exactly where the placement mirrors, and name the
//! primitive's vertex indices in that order as its source vertices.

use std::path::Path;

use bvhc::import::{ImportOptions, SceneFormat, SceneSelector, import};
use glam::{DMat4, DVec3};

use crate::common::scene;

/// World matrices of every node reachable from the default scene, by node index.
pub(crate) fn world_matrices(document: &gltf::Document) -> Vec<Option<DMat4>> {
    let mut worlds = vec![None; document.nodes().len()];
    let scene = document.default_scene().or_else(|| document.scenes().next()).unwrap();
    let mut stack: Vec<(gltf::Node, DMat4)> = scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
    while let Some((node, parent)) = stack.pop() {
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        worlds[node.index()] = Some(world);
        stack.extend(node.children().map(|c| (c, world)));
    }
    worlds
}

/// A primitive as the oracle decodes it: local positions and its index list.
type LocalPrimitive = (Vec<[f32; 3]>, Vec<u32>);

/// Imports `relative` and checks every triangle against the oracle; returns (triangles, mirrored ones).
fn check_against_oracle(relative: &str) -> Option<(usize, usize)> {
    let path = scene(relative)?;
    let imported = import(&path, &ImportOptions { keep_degenerate: true, ..Default::default() }).unwrap();
    let (document, buffers) = load_with_gltf_crate(&path);
    let worlds = world_matrices(&document);
    let soup = &imported.soup;
    let mut mirrored = 0;
    let mut decoded: std::collections::HashMap<(u32, u32), LocalPrimitive> = Default::default();
    for (t, &id) in soup.source_ids.iter().enumerate() {
        let range = soup.source_of(id).unwrap();
        let k = (id - range.first_source_triangle) as usize;
        let (positions, indices) = decoded.entry((range.mesh_index, range.primitive_index)).or_insert_with(|| {
            let mesh = document.meshes().nth(range.mesh_index as usize).unwrap();
            let primitive = mesh.primitives().nth(range.primitive_index as usize).unwrap();
            assert_eq!(primitive.mode(), gltf::mesh::Mode::Triangles, "the oracle handles TRIANGLES only");
            let reader = primitive.reader(|b| Some(buffers[b.index()].as_slice()));
            let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
            let indices: Vec<u32> = match reader.read_indices() {
                Some(indices) => indices.into_u32().collect(),
                None => (0..positions.len() as u32).collect(),
            };
            (positions, indices)
        });
        let world = worlds[range.node_index as usize].unwrap();
        let mut local = [indices[3 * k], indices[3 * k + 1], indices[3 * k + 2]];
        if world.determinant() < 0.0 {
            local.swap(1, 2);
            mirrored += 1;
        }
        // The source vertices are the primitive's indices in the stored corner order (spec 5.9).
        assert_eq!(soup.source_vertices[t], local, "{relative} triangle {t}");
        let expected = local.map(|i| {
            let p = positions[i as usize].map(f64::from);
            world.transform_point3(DVec3::from_array(p))
        });
        let got = soup.vertices(t);
        for (corner, (g, e)) in got.iter().zip(&expected).enumerate() {
            let scale = e.abs().max_element().max(1.0);
            let error = (DVec3::from_array(g.map(f64::from)) - *e).abs().max_element();
            assert!(error <= 1e-6 * scale, "{relative} triangle {t} corner {corner}: {g:?} vs {e:?}");
        }
    }
    Some((soup.triangles.len(), mirrored))
}

pub(crate) fn load_with_gltf_crate(path: &Path) -> (gltf::Document, Vec<Vec<u8>>) {
    let gltf = gltf::Gltf::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let buffers = gltf
        .document
        .buffers()
        .map(|buffer| match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().unwrap(),
            gltf::buffer::Source::Uri(uri) => std::fs::read(path.parent().unwrap().join(uri)).unwrap(),
        })
        .collect();
    (gltf.document, buffers)
}

#[test]
fn mirrored_instances_of_negative_scale_test_have_flipped_winding() {
    let Some((triangles, mirrored)) = check_against_oracle("khr-negative-scale-test/NegativeScaleTest.gltf") else {
        return;
    };
    assert_eq!(triangles, 7724);
    assert!(mirrored > 1000, "{mirrored} triangles in mirrored placements");
}

#[test]
fn placed_triangles_equal_the_gltf_crate_oracle() {
    for relative in [
        "khr-2cylinder-engine/2CylinderEngine.gltf",
        "khr-cesium-milk-truck/CesiumMilkTruck.gltf",
        "khr-orientation-test/OrientationTest.gltf",
        "khr-simple-meshes/SimpleMeshes.gltf",
        "khr-box/Box.glb",
        "khr-triangle-without-indices/TriangleWithoutIndices.gltf",
        "khr-toy-car/ToyCar.gltf",
        "trimesh-no-indices-3storybuilding/no_indices_3storybuilding.glb",
        "khr-simple-sparse-accessor/SimpleSparseAccessor.gltf",
    ] {
        if let Some((triangles, _)) = check_against_oracle(relative) {
            assert!(triangles > 0, "{relative}");
        }
    }
}

#[test]
fn mesh_primitive_modes_gives_exactly_its_triangle_modes() {
    let Some(path) = scene("khr-mesh-primitive-modes/MeshPrimitiveModes.gltf") else { return };
    let imported = import(&path, &ImportOptions::default()).unwrap();
    // Meshes 0-3 are points, lines, line loop and line strip; 4-6 triangles (6 indices), strip (6), fan (8).
    assert_eq!(imported.report.skipped_point_and_line_primitives, 4);
    let per_mesh: Vec<(u32, u32)> =
        imported.soup.sources.iter().map(|r| (r.mesh_index, r.source_triangle_count)).collect();
    assert_eq!(per_mesh, [(4, 6), (5, 4), (6, 6)]);
    assert_eq!(imported.soup.triangles.len(), 16);
    // Strip and fan triangles keep the winding of the first one (all face +z here).
    for t in 0..imported.soup.triangles.len() {
        let [a, b, c] = imported.soup.vertices(t);
        let z = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        assert!(z > 0.0, "triangle {t} faces -z");
    }
}

#[test]
fn gpu_instancing_places_every_instance() {
    let Some(path) = scene("khr-simple-instancing/SimpleInstancing.gltf") else { return };
    let imported = import(&path, &ImportOptions::default()).unwrap();
    assert_eq!(imported.soup.triangles.len(), 1500);
    let instances: std::collections::BTreeSet<u32> = imported.soup.sources.iter().map(|r| r.instance_index).collect();
    assert_eq!(instances, (0..125).collect());
    assert_eq!(imported.report.unique_source_triangles, 12);
    // Instances are spread out: their centers are distinct.
    let mut centers: Vec<[i64; 3]> = imported
        .soup
        .sources
        .iter()
        .map(|r| {
            let t = imported.soup.source_ids.iter().position(|&id| id == r.first_source_triangle).unwrap();
            imported.soup.vertices(t)[0].map(|c| (c * 1000.0) as i64)
        })
        .collect();
    centers.sort_unstable();
    centers.dedup();
    assert_eq!(centers.len(), 125);
}

#[test]
fn quantized_lantern_matches_the_original_within_the_quantization_step() {
    let (Some(original), Some(quantized)) =
        (scene("khr-lantern/Lantern.gltf"), scene("khr-lantern-quantized/Lantern.gltf"))
    else {
        return;
    };
    let options = ImportOptions { keep_degenerate: true, ..Default::default() };
    let original = import(&original, &options).unwrap().soup;
    let quantized = import(&quantized, &options).unwrap().soup;
    assert_eq!(original.triangles.len(), quantized.triangles.len());
    // The step per axis: the smallest gap between distinct quantized coordinates.
    let step: [f64; 3] = std::array::from_fn(|a| {
        let mut values: Vec<f64> = quantized.positions.iter().map(|p| f64::from(p[a])).collect();
        values.sort_by(f64::total_cmp);
        values.dedup();
        values.windows(2).map(|w| w[1] - w[0]).fold(f64::INFINITY, f64::min)
    });
    assert!(step.iter().all(|s| *s > 0.0 && *s < 0.01), "{step:?}");
    // Every quantized vertex lies within one step of an original vertex (grid search around its cell).
    let cell = 4.0 * step.iter().cloned().fold(0.0, f64::max);
    let key = |p: &[f32; 3]| p.map(|c| (f64::from(c) / cell).floor() as i64);
    let mut grid: std::collections::HashMap<[i64; 3], Vec<[f32; 3]>> = Default::default();
    for p in &original.positions {
        grid.entry(key(p)).or_default().push(*p);
    }
    for q in &quantized.positions {
        let k = key(q);
        let near =
            (-1..=1).flat_map(|x| (-1..=1).flat_map(move |y| (-1..=1).map(move |z| [k[0] + x, k[1] + y, k[2] + z])));
        let found = near
            .filter_map(|c| grid.get(&c))
            .flatten()
            .any(|o| (0..3).all(|a| (f64::from(o[a]) - f64::from(q[a])).abs() <= step[a] * 1.0001));
        assert!(found, "quantized vertex {q:?} is more than one step from every original vertex");
    }
}

#[test]
fn scenes_are_chosen_by_index_and_name_and_default() {
    let Some(path) = scene("khr-multiple-scenes/MultipleScenes.gltf") else { return };
    let count = |scene| import(&path, &ImportOptions { scene, ..Default::default() }).map(|i| i.soup.triangles.len());
    // The default scene is scene 1 (a square); scene 0 holds a single triangle.
    assert_eq!(count(None).unwrap(), 2);
    assert_eq!(count(Some(SceneSelector::Index(1))).unwrap(), 2);
    assert_eq!(count(Some(SceneSelector::Index(0))).unwrap(), 1);
    let error = count(Some(SceneSelector::Index(7))).unwrap_err().to_string();
    assert!(error.contains("scene 7 does not exist"), "{error}");
    let error = count(Some(SceneSelector::Name("nope".into()))).unwrap_err().to_string();
    assert!(error.contains("no scene is named 'nope'"), "{error}");
}

#[test]
fn every_file_read_is_listed_and_images_are_not_read() {
    let Some(path) = scene("khr-damaged-helmet/DamagedHelmet.gltf") else { return };
    let imported = import(&path, &ImportOptions::default()).unwrap();
    let names: Vec<String> =
        imported.files_read.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["DamagedHelmet.gltf", "DamagedHelmet.bin"]);
    assert_eq!(imported.format, SceneFormat::Gltf);
}
