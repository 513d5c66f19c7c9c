//! Caps over a mesh's holes, which make its winding number a count of ray crossings plus a small correction
//! (`crate::tracer::winding`).
//!
//! The winding number of a surface `S` with no boundary (every edge met by as many triangles one way as the
//! other) is an integer at every point off it: the sum of the sides of the crossings of any ray from the point
//! (`crate::ray::moved`), which the watertight test counts exactly. A surface with holes has a boundary `dS`,
//! a chain of edges; a **cap** `C` is a surface with `dC = -dS`, so that `S + C` has none, and then
//! `w_S(p) = crossings of S + C - w_C(p)`: an exact integer and the winding number of the caps, which is small
//! (caps span holes, not the surface) and is summed as the mesh's own is (Barill et al. 2018, over a tree of the
//! caps: `crate::point::winding`). Here the boundary is found by summing each triangle's directed edges (vertices
//! equal when their coordinates are), split into closed walks, and each walk triangulated with its own vertices
//! (`triangulate_loop`), so the caps are f32 triangles whose edges shared with the mesh are decided by the same
//! arithmetic as the mesh's own. A closed mesh has no caps.

use std::collections::hash_map::Entry;
use std::collections::{HashMap, TryReserveError};
use std::hash::{BuildHasherDefault, Hasher};

use crate::format::{PackedNode, PackedTriangle};
use crate::point::Point3;
use crate::point::winding::{Map, MeshMoments, mesh_angle, mesh_moments};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::moved::moved_side;

/// A vertex as the boundary compares it: its coordinates' bits, `-0.0` as `0.0`.
type VertexKey = [u32; 3];

/// Triangles a cap tree's leaf holds at most.
const LEAF_SIZE: usize = 4;

/// The caps of one mesh: their triangles in a binary tree laid out as a file's (children after their parent)
/// and the tree's winding moments.
#[derive(Clone, Debug)]
pub(crate) struct Caps {
    nodes: Vec<PackedNode>,
    triangles: Vec<PackedTriangle>,
    moments: MeshMoments,
}

/// The ambiguity a cap crossing count can meet: a cap within `near` of the ray's origin.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct NearCap;

impl Caps {
    /// The caps of the mesh of `triangles` whose `counted` records count (`None`: all); `None` when the mesh has
    /// no boundary.
    pub(crate) fn of(triangles: &[PackedTriangle], counted: Option<&[bool]>) -> Result<Option<Caps>, TryReserveError> {
        let boundary = boundary_edges(triangles, counted)?;
        if boundary.is_empty() {
            return Ok(None);
        }
        let mut caps = cap_triangles(&boundary)?;
        let nodes = build_tree(&mut caps)?;
        let moments = mesh_moments(&nodes, &caps, None, false)?;
        Ok(Some(Caps { nodes, triangles: caps, moments }))
    }

    /// The solid angle of the caps at `p` (world space), placed by `map` (`None`: in world space already),
    /// summed as `crate::point::winding::mesh_angle` sums a mesh's.
    pub(crate) fn angle(&self, p: Point3, map: Option<&Map>) -> f64 {
        mesh_angle(&self.nodes, &self.triangles, &self.moments, p, map)
    }

    /// The sides of `ray`'s crossings of the caps at `t > 0` summed (as `crate::ray::moved::moved_side` counts
    /// them), or [`NearCap`] when a cap the ray's line crosses does so within `near` of the origin, where the
    /// side of the origin is not certain.
    pub(crate) fn crossings(&self, ray: &Ray, near: f32) -> Result<i64, NearCap> {
        let prepared = PreparedRay::new(&Ray { t_min: -near, t_max: f32::INFINITY, ..*ray });
        let mut stack = crate::walk_stack::WalkStack::<u32, { crate::format::MAX_DEPTH }>::new();
        let mut total = 0;
        let mut next = Some(0u32);
        while let Some(index) = next.take().or_else(|| stack.pop()) {
            let Some(node) = self.nodes.get(index as usize) else { continue };
            if prepared.enter_box(node, f32::INFINITY).is_none() {
                continue;
            }
            if node.is_leaf() {
                let end = node.index as usize + node.count as usize;
                for triangle in self.triangles.get(node.index as usize..end).unwrap_or(&[]) {
                    let side = moved_side(&prepared, triangle);
                    if side == 0 {
                        continue;
                    }
                    match crossing_distance(ray, triangle) {
                        Some(t) if t.abs() > f64::from(near) => total += if t > 0.0 { i64::from(side) } else { 0 },
                        _ => return Err(NearCap),
                    }
                }
            } else {
                stack.push(node.index + 1);
                next = Some(node.index);
            }
        }
        Ok(total)
    }
}

/// Where `ray`'s line meets `triangle`'s plane, in binary64 (`None` when it runs along the plane).
fn crossing_distance(ray: &Ray, triangle: &PackedTriangle) -> Option<f64> {
    let [a, b, c] = triangle.vertices.map(|v| v.map(f64::from));
    let sub = |x: Point3, y: Point3| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let (e1, e2) = (sub(b, a), sub(c, a));
    let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    let dot = |x: Point3, y: Point3| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let along = dot(n, ray.direction.map(f64::from));
    (along != 0.0).then(|| dot(n, sub(a, ray.origin.map(f64::from))) / along)
}

/// A multiply-and-rotate hasher for the boundary's edge keys (the default hasher is several times slower on a
/// mesh's millions of edges; the keys are coordinates, not attacker-chosen collisions that matter: the worst
/// case is a slower build).
#[derive(Default)]
struct EdgeHasher(u64);

impl Hasher for EdgeHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for chunk in bytes.chunks(8) {
            let mut word = [0u8; 8];
            word[..chunk.len()].copy_from_slice(chunk);
            self.0 = (self.0.rotate_left(26) ^ u64::from_le_bytes(word)).wrapping_mul(0x9e37_79b9_7f4a_7c15);
        }
    }
}

fn key(v: [f32; 3]) -> VertexKey {
    v.map(|c| if c == 0.0 { 0 } else { c.to_bits() })
}

fn vertex(k: VertexKey) -> [f32; 3] {
    k.map(f32::from_bits)
}

/// The boundary of the counted triangles: each edge `(a, b)` with `a < b` (by key) and its multiplicity `m`
/// (the chain holds `a -> b` `m` times, `b -> a` for negative `m`), sorted.
fn boundary_edges(
    triangles: &[PackedTriangle],
    counted: Option<&[bool]>,
) -> Result<Vec<(VertexKey, VertexKey, i32)>, TryReserveError> {
    // Interior edges cancel as soon as their second triangle is read and leave the map, and the records come
    // in the tree's order (neighbours near each other), so the map holds about the frontier of the records read
    // so far, not every edge.
    let mut chain: HashMap<(VertexKey, VertexKey), i32, BuildHasherDefault<EdgeHasher>> = HashMap::default();
    for (index, triangle) in triangles.iter().enumerate() {
        if counted.is_some_and(|c| c.get(index) != Some(&true)) {
            continue;
        }
        let [a, b, c] = triangle.vertices.map(key);
        for (from, to) in [(a, b), (b, c), (c, a)] {
            let (edge, side) = match from.cmp(&to) {
                std::cmp::Ordering::Less => ((from, to), 1),
                std::cmp::Ordering::Greater => ((to, from), -1),
                std::cmp::Ordering::Equal => continue,
            };
            chain.try_reserve(1)?;
            match chain.entry(edge) {
                Entry::Occupied(mut multiplicity) => {
                    *multiplicity.get_mut() += side;
                    if *multiplicity.get() == 0 {
                        multiplicity.remove();
                    }
                }
                Entry::Vacant(slot) => {
                    slot.insert(side);
                }
            }
        }
    }
    let mut boundary = Vec::new();
    boundary.try_reserve_exact(chain.values().filter(|&&m| m != 0).count())?;
    boundary.extend(chain.into_iter().filter(|&(_, m)| m != 0).map(|((a, b), m)| (a, b, m)));
    boundary.sort_unstable();
    Ok(boundary)
}

/// The cap triangles of a boundary: the chain split into closed walks, each triangulated with its own vertices
/// ([`triangulate_loop`]) with the winding turned.
fn cap_triangles(boundary: &[(VertexKey, VertexKey, i32)]) -> Result<Vec<PackedTriangle>, TryReserveError> {
    // The chain's edges, each as often as its multiplicity, directed as the chain holds them, sorted by source.
    let total: usize = boundary.iter().map(|&(_, _, m)| m.unsigned_abs() as usize).sum();
    let mut edges: Vec<(VertexKey, VertexKey)> = Vec::new();
    edges.try_reserve_exact(total)?;
    for &(a, b, m) in boundary {
        let edge = if m > 0 { (a, b) } else { (b, a) };
        edges.extend(std::iter::repeat_n(edge, m.unsigned_abs() as usize));
    }
    edges.sort_unstable();
    // Every vertex of a boundary has as many edges in as out, so a walk along unused edges from a vertex can only
    // stop back at it: each walk is a closed loop. Edges out of a vertex are contiguous and taken lowest first,
    // so a count a vertex (kept at its first edge's index) says which is next.
    let mut taken: Vec<u32> = Vec::new();
    taken.try_reserve_exact(edges.len())?;
    taken.resize(edges.len(), 0);
    let first_out = |at: VertexKey| edges.partition_point(|&(from, _)| from < at);
    let take = |at: VertexKey, taken: &mut [u32]| {
        let out = first_out(at);
        let next = out + taken[out] as usize;
        (next < edges.len() && edges[next].0 == at).then(|| {
            taken[out] += 1;
            next
        })
    };
    let mut walk: Vec<VertexKey> = Vec::new();
    let mut caps = Vec::new();
    caps.try_reserve_exact(total)?;
    let mut source = 0; // the first edge out of the vertex walks start from
    while source < edges.len() {
        let start = edges[source].0;
        let Some(mut edge) = take(start, &mut taken) else {
            source += edges[source..].partition_point(|&(from, _)| from == start); // the next vertex's edges
            continue;
        };
        walk.clear();
        loop {
            walk.try_reserve(1)?;
            walk.push(edges[edge].0);
            let at = edges[edge].1;
            if at == start {
                break;
            }
            match take(at, &mut taken) {
                Some(e) => edge = e,
                None => break, // not a boundary (cannot happen): the walk is closed where it stopped
            }
        }
        triangulate_loop(&walk, &mut caps)?;
    }
    Ok(caps)
}

/// Triangles over the closed walk `w_0 -> w_1 -> ... -> w_0`, turned so that their boundary is the walk reversed:
/// the polygon split by the triangle of its first, middle and last vertices, and each of the two arcs left, with
/// the chord closing it, split the same way. A triangle spans an arc of the walk about half its parent's, so the
/// caps of a long rim are small near the rim (the large ones cross the hole), which keeps the caps' sum cheap
/// near it: `n - 2` triangles for `n` vertices.
fn triangulate_loop(walk: &[VertexKey], caps: &mut Vec<PackedTriangle>) -> Result<(), TryReserveError> {
    let mut arcs = vec![(0usize, walk.len().saturating_sub(1))];
    while let Some((i, j)) = arcs.pop() {
        if j < i + 2 {
            continue;
        }
        let m = (i + j) / 2;
        // `(w_i, w_m, w_j)` has the boundary `w_i -> w_m -> w_j -> w_i`, which with the arcs' gives the walk.
        caps.try_reserve(1)?;
        caps.push(PackedTriangle { vertices: [vertex(walk[i]), vertex(walk[j]), vertex(walk[m])] });
        arcs.push((m, j));
        arcs.push((i, m));
    }
    Ok(())
}

/// A binary tree over `triangles` (reordered), split at the median centroid along the longest axis of the
/// centroids' box, leaves of up to [`LEAF_SIZE`] triangles, in a file's layout: the root first, each inner
/// node's two children together after it. Boxes are padded by `2^-16` of the root's size and `2^-20` of each
/// coordinate, so that the ray test never culls a cap the crossing test meets.
fn build_tree(triangles: &mut [PackedTriangle]) -> Result<Vec<PackedNode>, TryReserveError> {
    let mut nodes: Vec<PackedNode> = Vec::new();
    nodes.try_reserve_exact((2 * triangles.len() / LEAF_SIZE + 1).max(1) * 2)?;
    let centroid = |t: &PackedTriangle, axis: usize| t.vertices.iter().map(|v| f64::from(v[axis])).sum::<f64>();
    let (root_min, root_max) = bounds(triangles);
    let pad = (0..3).map(|k| f64::from(root_max[k]) - f64::from(root_min[k])).fold(0.0, f64::max) / 65536.0;
    nodes.push(PackedNode { min: [0.0; 3], max: [0.0; 3], index: 0, count: 0 });
    let mut work = vec![(0usize, 0usize, triangles.len())];
    while let Some((node, first, end)) = work.pop() {
        let slice = &mut triangles[first..end];
        let (min, max) = bounds(slice);
        nodes[node].min = std::array::from_fn(|k| padded(min[k], -pad));
        nodes[node].max = std::array::from_fn(|k| padded(max[k], pad));
        if slice.len() <= LEAF_SIZE {
            (nodes[node].index, nodes[node].count) = (first as u32, slice.len() as u32);
            continue;
        }
        let spread = |axis: usize| {
            let values = slice.iter().map(|t| centroid(t, axis));
            values.clone().fold(f64::NEG_INFINITY, f64::max) - values.fold(f64::INFINITY, f64::min)
        };
        let axis = (0..3).fold(0, |best, axis| if spread(axis) > spread(best) { axis } else { best });
        let middle = slice.len() / 2;
        slice.select_nth_unstable_by(middle, |x, y| centroid(x, axis).total_cmp(&centroid(y, axis)));
        let children = nodes.len();
        nodes.try_reserve(2)?;
        nodes.push(PackedNode { min: [0.0; 3], max: [0.0; 3], index: 0, count: 0 });
        nodes.push(PackedNode { min: [0.0; 3], max: [0.0; 3], index: 0, count: 0 });
        nodes[node].index = children as u32;
        work.push((children + 1, first + middle, end));
        work.push((children, first, first + middle));
    }
    Ok(nodes)
}

/// The box of `triangles`' vertices.
fn bounds(triangles: &[PackedTriangle]) -> ([f32; 3], [f32; 3]) {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for v in triangles.iter().flat_map(|t| &t.vertices) {
        for k in 0..3 {
            min[k] = min[k].min(v[k]);
            max[k] = max[k].max(v[k]);
        }
    }
    (min, max)
}

/// `x` moved outward by `pad` (its sign says which way) and by `2^-20` of itself, rounded to f32 (at least 8
/// ulps of `x`, so the rounding cannot undo the move).
fn padded(x: f32, pad: f64) -> f32 {
    let x = f64::from(x);
    (x + pad + (x.abs() / 1_048_576.0).copysign(pad)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn triangle(vertices: [[f32; 3]; 3]) -> PackedTriangle {
        PackedTriangle { vertices }
    }

    fn tetrahedron() -> Vec<PackedTriangle> {
        let [a, b, c, d] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        vec![triangle([a, c, b]), triangle([a, b, d]), triangle([a, d, c]), triangle([b, c, d])]
    }

    /// Triangles from a small generator: points on a coarse grid, so that some share vertices and edges.
    fn grid_soup(seed: u64, count: usize) -> Vec<PackedTriangle> {
        let mut state = seed;
        let mut next = || {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            ((state >> 33) % 4) as f32 * 0.5
        };
        (0..count).map(|_| triangle(std::array::from_fn(|_| std::array::from_fn(|_| next())))).collect()
    }

    #[test]
    fn a_closed_mesh_has_no_caps_and_an_open_one_closes_with_its_caps() {
        assert!(Caps::of(&tetrahedron(), None).unwrap().is_none());
        let mut doubled = tetrahedron();
        doubled.push(doubled[3]); // a face twice: its edges are boundary (multiplicity 1 each)
        let mut open = tetrahedron();
        open.pop();
        for (name, mesh) in [("open", open), ("doubled face", doubled), ("soup", grid_soup(3, 60))] {
            let caps = Caps::of(&mesh, None).unwrap().expect(name);
            let mut closed = mesh.clone();
            closed.extend(&caps.triangles);
            assert!(boundary_edges(&closed, None).unwrap().is_empty(), "{name}: mesh and caps leave a boundary");
            // The tree holds every cap once, children after their parents, boxes around their triangles.
            let mut seen = vec![0; caps.triangles.len()];
            for (index, node) in caps.nodes.iter().enumerate() {
                if node.is_leaf() {
                    for t in node.index..node.index + node.count {
                        seen[t as usize] += 1;
                        for v in caps.triangles[t as usize].vertices {
                            assert!((0..3).all(|k| node.min[k] < v[k] && v[k] < node.max[k]), "{name}");
                        }
                    }
                } else {
                    assert!(node.index as usize > index, "{name}");
                }
            }
            assert!(seen.iter().all(|&n| n == 1), "{name}");
        }
    }

    #[test]
    fn uncounted_records_leave_the_boundary_and_a_cap_at_the_origin_is_near() {
        let mut mesh = tetrahedron();
        mesh.push(mesh[0]); // a second record of a face, not counted: still closed
        let counted = [true, true, true, true, false];
        assert!(Caps::of(&mesh, Some(&counted)).unwrap().is_none());
        // One triangle: its cap is itself reversed, fanned from its centroid.
        let one = [triangle([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])];
        let caps = Caps::of(&one, None).unwrap().unwrap();
        assert_eq!(caps.triangles.len(), 1);
        let up = |z: f32| Ray::new([0.2, 0.25, z], [0.1, 0.05, 1.0]);
        // From below, the ray arrives at the caps' front side (they face -z) at t > 0; from above they are behind.
        assert_eq!(caps.crossings(&up(-1.0), 1e-6), Ok(-1));
        assert_eq!(caps.crossings(&up(1.0), 1e-6), Ok(0));
        assert_eq!(caps.crossings(&up(0.0), 1e-6), Err(NearCap));
    }
}
