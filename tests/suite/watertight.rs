//! Watertightness: rays from inside closed meshes, and rays aimed exactly at shared vertices and edges, never
//! slip through, in files as converted and in a file refit to a deformed pose.

use bvhc::loader::Ray;
use bvhc_loader::Trace;
use rand::RngExt;

use crate::common::*;

/// The shared icosphere with radius `radius`, rounded to f32 (shared vertices round identically).
fn icosphere(levels: usize, radius: f32) -> (Vec<[f32; 3]>, Vec<[usize; 3]>) {
    let (vertices, faces) = unit_icosphere(levels);
    (vertices.iter().map(|p| p.map(|c| (c * f64::from(radius)) as f32)).collect(), faces)
}

/// A cube `[-1, 1]^3` whose faces are `n x n` grids of axis-aligned quads (two triangles each).
fn grid_cube(n: usize) -> (Vec<[f32; 3]>, Vec<[usize; 3]>) {
    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    let coordinate = |i: usize| -1.0 + 2.0 * i as f32 / n as f32;
    for axis in 0..3 {
        for side in [-1.0f32, 1.0] {
            let base = vertices.len();
            for i in 0..=n {
                for j in 0..=n {
                    let mut p = [0.0; 3];
                    p[axis] = side;
                    p[(axis + 1) % 3] = coordinate(i);
                    p[(axis + 2) % 3] = coordinate(j);
                    vertices.push(p);
                }
            }
            for i in 0..n {
                for j in 0..n {
                    let at = |di: usize, dj: usize| base + (i + di) * (n + 1) + j + dj;
                    faces.push([at(0, 0), at(1, 0), at(1, 1)]);
                    faces.push([at(0, 0), at(1, 1), at(0, 1)]);
                }
            }
        }
    }
    // The cube's edges are shared by two faces with separate vertex copies at identical positions.
    (vertices, faces)
}

fn soup(vertices: &[[f32; 3]], faces: &[[usize; 3]]) -> Vec<Triangle> {
    faces.iter().map(|f| f.map(|v| vertices[v])).collect()
}

/// Rays from each origin to every vertex, to every edge's midpoint, and in 2000 random directions.
fn rays_at_vertices_and_edges(origins: &[[f32; 3]], vertices: &[[f32; 3]], faces: &[[usize; 3]]) -> Vec<Ray> {
    let mut rays: Vec<Ray> = Vec::new();
    let mut rng = rng(60);
    for &origin in origins {
        for v in vertices {
            rays.push(Ray::new(origin, std::array::from_fn(|a| v[a] - origin[a])));
        }
        for f in faces {
            for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
                let mid: [f32; 3] = std::array::from_fn(|k| (vertices[a][k] + vertices[b][k]) * 0.5);
                rays.push(Ray::new(origin, std::array::from_fn(|k| mid[k] - origin[k])));
            }
        }
        for _ in 0..2000 {
            rays.push(Ray::new(origin, random_point(&mut rng, 1.0)));
        }
    }
    rays
}

fn assert_all_hit(name: &str, triangles: &[Triangle], rays: &[Ray]) {
    for max_leaf_size in [1, 4] {
        let tree = packed_tree(triangles, max_leaf_size);
        let file = write_file(&tree);
        let tracer = file.view().tracer();
        let misses: Vec<&Ray> = rays.iter().filter(|ray| tracer.closest_hit(ray).is_none()).collect();
        assert!(misses.is_empty(), "{name}: {} of {} rays missed, first {:?}", misses.len(), rays.len(), misses[0]);
        assert!(rays.iter().all(|ray| tracer.any_hit(ray)), "{name}: any-hit missed");
    }
    let wide = crate::common::wide_bvh(triangles);
    for path in crate::common::kernel_paths() {
        let tracer = bvhc::loader::WideTracer::new(&wide, None, path);
        let misses = rays.iter().filter(|ray| tracer.closest_hit(ray).is_none()).count();
        assert_eq!(misses, 0, "{name}: the wide kernel ({path:?}) missed {misses} of {} rays", rays.len());
        assert!(rays.iter().all(|ray| tracer.any_hit(ray)), "{name}: wide any-hit ({path:?}) missed");
    }
}

#[test]
fn rays_from_inside_a_closed_sphere_at_every_vertex_and_edge_hit() {
    let (vertices, faces) = icosphere(3, 2.0);
    let triangles = soup(&vertices, &faces);
    let rays = rays_at_vertices_and_edges(&[[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [1.9, 0.0, 0.0]], &vertices, &faces);
    assert_all_hit("icosphere", &triangles, &rays);
}

#[test]
fn rays_from_outside_aimed_at_shared_vertices_hit() {
    let (vertices, faces) = icosphere(2, 1.0);
    let triangles = soup(&vertices, &faces);
    let mut rng = rng(61);
    let rays: Vec<Ray> = vertices
        .iter()
        .map(|v| {
            let origin: [f32; 3] = std::array::from_fn(|a| v[a] * 3.0 + rng.random_range(-0.5..0.5));
            Ray::new(origin, std::array::from_fn(|a| v[a] - origin[a]))
        })
        .collect();
    assert_all_hit("icosphere from outside", &triangles, &rays);
}

#[test]
fn axis_parallel_rays_through_grid_edges_and_vertices_of_a_closed_cube_hit() {
    let n = 8;
    let (vertices, faces) = grid_cube(n);
    let triangles = soup(&vertices, &faces);
    let grid: Vec<f32> = (0..=n).map(|i| -1.0 + 2.0 * i as f32 / n as f32).collect();
    let mut rays = Vec::new();
    for &x in &grid[1..n] {
        for &y in &grid[1..n] {
            for axis in 0..3 {
                for sign in [1.0f32, -1.0] {
                    let mut origin = [0.0f32; 3];
                    origin[(axis + 1) % 3] = x;
                    origin[(axis + 2) % 3] = y;
                    // Exactly axis-parallel, with the other components +0 and -0.
                    let mut direction = [0.0f32, -0.0, 0.0];
                    direction[axis] = sign;
                    rays.push(Ray::new(origin, direction));
                    // Through grid vertices of the far face from the cube's center.
                    let mut target = origin;
                    target[axis] = sign;
                    rays.push(Ray::new([0.0; 3], target));
                }
            }
        }
    }
    // Rays that start exactly on a face and run inside it, along a grid line, towards the opposite edge.
    for &x in &grid[1..n] {
        rays.push(Ray::new([x, -1.0, 1.0], [0.0, 1.0, -0.0]));
    }
    assert_all_hit("grid cube", &triangles, &rays);
}

#[test]
fn a_closed_sphere_refit_to_a_deformed_pose_stays_watertight_on_every_kernel() {
    // The sphere converted as an OBJ (vertices shared), then refit to a smooth deformation of its vertices: the
    // records' shared corners move alike, so the refit mesh is closed, and rays from inside it at its vertices
    // and edges, as above, must all hit, on the binary kernel and the wide one on every path.
    let (vertices, faces) = icosphere(3, 2.0);
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("sphere.obj");
    let mut text: String = vertices.iter().map(|v| format!("v {} {} {}\n", v[0], v[1], v[2])).collect();
    text.extend(faces.iter().map(|f| format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1)));
    std::fs::write(&obj, text).unwrap();
    let output = dir.path().join("sphere.bvh");
    let overrides = bvhc::options::Overrides { splits: Some(false), ..Default::default() };
    bvhc::Conversion::new(&obj, &output).overrides(overrides).run().unwrap();
    let mut file = bvhc::loader::BvhFile::read(&output).unwrap();
    // A squash, a twist about z and a bulge: one-to-one, so inside stays inside.
    let deform = |[x, y, z]: [f32; 3]| {
        let (s, c) = (0.4 * z).sin_cos();
        let (x, y) = (1.4 * x, 0.6 * y);
        [x * c - y * s, x * s + y * c + 0.1 * x * x, z]
    };
    let moved: Vec<Triangle> = file.view().triangles().iter().map(|t| t.vertices.map(deform)).collect();
    file.refit(bvhc::loader::RefitPositions::Triangles(&moved), 2).unwrap();
    let deformed: Vec<[f32; 3]> = vertices.iter().map(|&v| deform(v)).collect();
    let origins = [[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [1.9, 0.0, 0.0], [0.0, 0.0, -1.9]].map(deform);
    let rays = rays_at_vertices_and_edges(&origins, &deformed, &faces);
    for tracer in every_kernel(&file.view()) {
        let misses = rays.iter().filter(|ray| tracer.closest_hit(ray).is_none()).count();
        assert_eq!(misses, 0, "{:?}: {misses} of {} rays missed the refit sphere", tracer.kernel(), rays.len());
        assert!(rays.iter().all(|ray| tracer.any_hit(ray)), "{:?}: any-hit missed", tracer.kernel());
    }
}
