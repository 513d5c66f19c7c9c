//! The source vertices (format 1.2, spec 5.9) against independent oracles: every stored corner is the source
//! vertex its index names (OBJ `v` records parsed here, PLY vertex records, glTF primitives of every mode decoded
//! by the gltf crate and placed by their nodes, mirrored placements included); hits on converted files
//! interpolate the source's own positions to the hit point; and the options that leave the section out.

use bvhc_loader::Trace;
use std::path::Path;

use bvhc::import::{ImportOptions, import};
use bvhc::loader::{BvhFile, Ray};
use glam::{DMat4, DVec3};

use crate::common::scene;
use crate::import_gltf::{load_with_gltf_crate, world_matrices};

/// An OBJ file's `v` records in file order, as f32 (a fourth number divides the three, as tobj does).
fn obj_v_records(text: &str) -> Vec<[f32; 3]> {
    text.lines()
        .filter_map(|line| {
            let mut words = line.split_whitespace();
            (words.next() == Some("v")).then(|| {
                let numbers: Vec<f64> = words.take(4).map(|w| w.parse().unwrap()).collect();
                let w = if numbers.len() == 4 { numbers[3] } else { 1.0 };
                [0, 1, 2].map(|a| (numbers[a] / w) as f32)
            })
        })
        .collect()
}

/// Imports `path` and checks that corner `c` of every triangle is, bit for bit, `records[source_vertices[c]]`.
fn assert_corners_are_records(path: &Path, records: &[[f32; 3]]) -> usize {
    let soup = import(path, &ImportOptions::default()).unwrap().soup;
    assert_eq!(soup.source_vertices.len(), soup.triangles.len());
    for (t, indices) in soup.source_vertices.iter().enumerate() {
        let expected = indices.map(|i| records[i as usize].map(f32::to_bits));
        assert_eq!(soup.vertices(t).map(|p| p.map(f32::to_bits)), expected, "{} triangle {t}", path.display());
    }
    soup.triangles.len()
}

#[test]
fn obj_source_vertices_are_the_files_v_records() {
    // Two models, a concave polygon (ear clipping), relative indices, and corners with texture and normal numbers.
    let dir = tempfile::tempdir().unwrap();
    let text = "o first\nv 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nvt 0 0\nvn 0 0 1\n\
                f 1/1/1 2/1/1 3/1/1 4/1/1 5/1/1 6/1/1\ng second\nv 5 5 0\nv 6 5 0\nv 5 6 0 0.5\nf -3//1 -2//1 -1//1\n\
                o third\nf 6 1 5\n";
    let path = dir.path().join("shapes.obj");
    std::fs::write(&path, text).unwrap();
    assert_eq!(assert_corners_are_records(&path, &obj_v_records(text)), 6);
    let soup = import(&path, &ImportOptions::default()).unwrap().soup;
    assert_eq!(soup.source_vertices[4], [6, 7, 8], "relative indices, counted over the whole file");
    assert_eq!(soup.source_vertices[5], [5, 0, 4], "a later model names earlier records");
    let teapot = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let mut scenes = vec![teapot];
    for relative in [
        "aj-cow/cow.obj",
        "trimesh-objcases/groups.obj",
        "trimesh-objcases/negative_indices.obj",
        "trimesh-objcases/polygonfaces.obj",
        "trimesh-objcases/face_in_group_name_mid_file.obj",
    ] {
        scenes.extend(scene(relative));
    }
    for path in scenes {
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(assert_corners_are_records(&path, &obj_v_records(&text)) > 0);
    }
}

#[test]
fn ply_source_vertices_are_the_vertex_records() {
    let dir = tempfile::tempdir().unwrap();
    let points: Vec<[f32; 3]> = (0..8).map(|i| [(i % 4) as f32, (i / 4) as f32, 0.25 * i as f32]).collect();
    let header = |element: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 8\nproperty float x\nproperty float y\nproperty float z\n\
             element {element} 2\nproperty list uchar int vertex_indices\nend_header\n"
        )
    };
    let vertices: String = points.iter().map(|p| format!("{} {} {}\n", p[0], p[1], p[2])).collect();
    let faces = format!("{}{vertices}4 0 1 5 4\n3 7 6 2\n", header("face"));
    let strips = format!("{}{vertices}6 0 4 1 5 2 6\n5 2 6 -1 3 7\n", header("tristrips"));
    for (name, text) in [("faces.ply", faces), ("strips.ply", strips)] {
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        assert!(assert_corners_are_records(&path, &points) >= 3, "{name}");
    }
}

/// Every triangle of the glTF at `relative` (nodes without GPU instancing): its corners are its primitive's
/// vertices `source_vertices` (decoded by the gltf crate) placed by its node, in order. Returns (triangles,
/// mirrored).
fn check_gltf(relative: &str) -> Option<(usize, usize)> {
    let path = scene(relative)?;
    let soup = import(&path, &ImportOptions::default()).unwrap().soup;
    let (document, buffers) = load_with_gltf_crate(&path);
    let worlds = world_matrices(&document);
    let (mut checked, mut mirrored) = (0, 0);
    for (t, &id) in soup.source_ids.iter().enumerate() {
        let range = soup.source_of(id).unwrap();
        let mesh = document.meshes().nth(range.mesh_index as usize).unwrap();
        let primitive = mesh.primitives().nth(range.primitive_index as usize).unwrap();
        let reader = primitive.reader(|b| Some(buffers[b.index()].as_slice()));
        let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        let world: DMat4 = worlds[range.node_index as usize].unwrap();
        mirrored += usize::from(world.determinant() < 0.0);
        for (corner, &index) in soup.source_vertices[t].iter().enumerate() {
            let placed = world.transform_point3(DVec3::from_array(positions[index as usize].map(f64::from)));
            let got = DVec3::from_array(soup.vertices(t)[corner].map(f64::from));
            let scale = placed.abs().max_element().max(1.0);
            assert!((got - placed).abs().max_element() <= 1e-6 * scale, "{relative} triangle {t} corner {corner}");
        }
        checked += 1;
    }
    Some((checked, mirrored))
}

#[test]
fn gltf_source_vertices_name_the_primitives_vertices_in_every_mode_and_placement() {
    if let Some((triangles, _)) = check_gltf("khr-mesh-primitive-modes/MeshPrimitiveModes.gltf") {
        assert_eq!(triangles, 16, "triangles, a strip and a fan");
    }
    if let Some((_, mirrored)) = check_gltf("khr-negative-scale-test/NegativeScaleTest.gltf") {
        assert!(mirrored > 1000, "{mirrored} triangles in mirrored placements");
    }
    for relative in [
        "khr-2cylinder-engine/2CylinderEngine.gltf",
        "khr-triangle-without-indices/TriangleWithoutIndices.gltf",
        "khr-simple-sparse-accessor/SimpleSparseAccessor.gltf",
        "trimesh-no-indices-3storybuilding/no_indices_3storybuilding.glb",
    ] {
        if let Some((triangles, _)) = check_gltf(relative) {
            assert!(triangles > 0, "{relative}");
        }
    }
}

#[test]
fn hits_interpolate_the_sources_own_positions_to_the_hit_point() {
    // The mirrored placements of the negative scale test: interpolating each primitive's POSITION (placed by its
    // node) with the hit's source corners gives the point the ray reached.
    let Some(path) = scene("khr-negative-scale-test/NegativeScaleTest.gltf") else { return };
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("scene.bvh");
    bvhc::Conversion::new(&path, &output).run().unwrap();
    let file = BvhFile::read(&output).unwrap();
    let view = file.view();
    assert_eq!(view.version(), (1, 2));
    let (document, buffers) = load_with_gltf_crate(&path);
    let worlds = world_matrices(&document);
    let root = view.nodes()[0];
    let extent = (0..3).map(|a| root.max[a] - root.min[a]).fold(0.0f32, f32::max);
    let tracer = view.tracer();
    let (mut hits, mut mirrored) = (0, 0);
    // Rays from random points around the scene towards the centroids of every third record.
    let origins = crate::common::random_rays(2025, view.triangles().len(), extent);
    for (record, around) in view.triangles().iter().zip(origins).step_by(3) {
        let target = [0, 1, 2].map(|a| (record.vertices[0][a] + record.vertices[1][a] + record.vertices[2][a]) / 3.0);
        let origin = [0, 1, 2].map(|a| target[a] + 2.0 * around.origin[a]);
        let aimed = [0, 1, 2].map(|a| target[a] - origin[a]);
        let Some(hit) = tracer.closest_hit(&Ray::new(origin, aimed)) else { continue };
        let corners = view.source_corners(&hit).unwrap();
        let mesh = document.meshes().nth(corners.range.mesh_index as usize).unwrap();
        let primitive = mesh.primitives().nth(corners.range.primitive_index as usize).unwrap();
        let reader = primitive.reader(|b| Some(buffers[b.index()].as_slice()));
        let world = worlds[corners.range.node_index as usize].unwrap();
        mirrored += usize::from(world.determinant() < 0.0);
        let placed: Vec<[f32; 3]> = reader
            .read_positions()
            .unwrap()
            .map(|p| world.transform_point3(DVec3::from_array(p.map(f64::from))).as_vec3().to_array())
            .collect();
        let point = corners.interpolate(&placed).unwrap();
        let reached = [0, 1, 2].map(|a| origin[a] + hit.t * aimed[a]);
        let error = (0..3).map(|a| (point[a] - reached[a]).abs()).fold(0.0f32, f32::max);
        assert!(error <= 1e-4 * extent, "hit {hit:?}: interpolated {point:?}, reached {reached:?}");
        hits += 1;
    }
    assert!(hits > 2000 && mirrored > 300, "{hits} hits, {mirrored} on mirrored placements");
}

#[test]
fn the_section_is_left_out_when_asked_or_without_ids() {
    let teapot = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let dir = tempfile::tempdir().unwrap();
    for (flag, version) in [("--no-source-vertices", (1, 1)), ("--no-ids", (1, 1))] {
        let output = dir.path().join("teapot.bvh");
        let run = crate::cli::bvhc(&[&teapot, &"-o", &output, &"--force", &flag]);
        assert!(run.status.success(), "{flag}: {}", String::from_utf8_lossy(&run.stderr));
        let file = BvhFile::read(&output).unwrap();
        assert_eq!(file.view().version(), version, "{flag}");
        assert!(file.view().source_vertices().is_none(), "{flag}");
        let metadata = crate::common::assert_metadata_matches_schema(&file);
        assert_eq!(metadata["build"]["write_source_vertices"], false, "{flag}");
    }
}
