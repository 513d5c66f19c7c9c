//! What every kernel returns and reports: the [`TriangleHit`] of one triangle test, the [`Hit`] record and the
//! traversal counters. (How far beyond a hit the kernels keep looking, so that they find the same closest hit,
//! is `crate::ray::reach`.)

use crate::format::{PACKET_LANES, PackedTriangle, TrianglePacket4};

/// A triangle hit: distance and barycentric coordinates; the hit point is `(1 - u - v) v0 + u v1 + v v2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Distance along the ray.
    pub t: f32,
    /// Weight of `v1`.
    pub u: f32,
    /// Weight of `v2`.
    pub v: f32,
}

/// The closest hit of a ray: what shading needs of the triangle it met.
///
/// `v0`, `v1`, `v2` are the triangle record's vertices as the file stores them (`format-spec/bvh-1.md` 5.2 and
/// 5.4 say which source corners they are, mirrored placements included).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray, in units of its direction.
    pub t: f32,
    /// Index of the triangle record in the file's triangles section. With split references one source
    /// triangle has several records: [`Hit::source_triangle_id`] names the triangle itself.
    pub triangle_index: u32,
    /// The triangle's source id from the triangle_ids section, when the file has one.
    pub source_triangle_id: Option<u32>,
    /// Barycentric weight of `v1`; the hit point is `(1 - u - v) v0 + u v1 + v v2`.
    pub u: f32,
    /// Barycentric weight of `v2`.
    pub v: f32,
    /// The geometric normal `(v1 - v0) x (v2 - v0)`, not normalized ([`geometric_normal`]): it points to the
    /// triangle's front side, from which `v0, v1, v2` appear counter-clockwise.
    pub normal: [f32; 3],
    /// Whether the ray arrived at the front side: `dot(direction, normal) < 0`.
    pub front_face: bool,
    /// In a two-level file (1.3), the index of the instance whose mesh was hit (in the `instances` section);
    /// `triangle_index` is then the mesh's record (in the triangles section, as always), `t`, `u` and `v` are
    /// those of the ray mapped into the mesh's object space (the same `t` as the world ray's, up to rounding),
    /// and `normal` is in world space (`format-spec/bvh-1.md` 11.3). `None` in a one-level file.
    pub instance_index: Option<u32>,
}

impl Hit {
    /// What an any-hit walk through instances passes up when a mesh occludes the ray: only its presence counts.
    pub(crate) const OCCLUSION: Hit = Hit {
        t: 0.0,
        triangle_index: u32::MAX,
        source_triangle_id: None,
        u: 0.0,
        v: 0.0,
        normal: [0.0; 3],
        front_face: false,
        instance_index: None,
    };

    /// The hit on record `triangle_index` of `triangles` (of the file) by a ray along `direction`, its source id
    /// looked up in `triangle_ids`.
    pub(crate) fn new(
        triangle_index: u32,
        hit: TriangleHit,
        triangles: &[PackedTriangle],
        triangle_ids: Option<&[u32]>,
        direction: &[f32; 3],
    ) -> Hit {
        Hit::on(triangle_index, triangles.get(triangle_index as usize), hit, triangle_ids, direction)
    }

    /// The hit in lane `address` ([`lane_address`]) of `packets` (the wide kernel's): the lane's triangle
    /// index, and the normal from the lane's own copy of the record's vertices (the same bits, V33), which the
    /// kernel has just read, rather than from the triangles section, which it has not (a cache miss a ray).
    pub(crate) fn in_lane(
        address: u32,
        hit: TriangleHit,
        packets: &[TrianglePacket4],
        triangle_ids: Option<&[u32]>,
        direction: &[f32; 3],
    ) -> Hit {
        let (packet, lane) = (address as usize / PACKET_LANES, address as usize % PACKET_LANES);
        match packets.get(packet) {
            Some(packet) => {
                let v = &packet.vertices;
                let vertex = |k: usize| [v[k][0][lane], v[k][1][lane], v[k][2][lane]];
                let triangle = PackedTriangle { vertices: [vertex(0), vertex(1), vertex(2)] };
                Hit::on(packet.triangle_index[lane], Some(&triangle), hit, triangle_ids, direction)
            }
            None => Hit::on(u32::MAX, None, hit, triangle_ids, direction),
        }
    }

    /// The hit on record `triangle_index`, whose vertices are `triangle`.
    fn on(
        triangle_index: u32,
        triangle: Option<&PackedTriangle>,
        hit: TriangleHit,
        triangle_ids: Option<&[u32]>,
        direction: &[f32; 3],
    ) -> Hit {
        let normal = triangle.map_or([0.0; 3], geometric_normal);
        let facing = direction[0] * normal[0] + direction[1] * normal[1] + direction[2] * normal[2];
        Hit {
            t: hit.t,
            triangle_index,
            source_triangle_id: triangle_ids.and_then(|ids| ids.get(triangle_index as usize).copied()),
            u: hit.u,
            v: hit.v,
            normal,
            front_face: facing < 0.0,
            instance_index: None,
        }
    }
}

/// A hit as the batch calls hand it off lean ([`crate::Trace::closest_hit_cores_with`]): what the walk found
/// (`t`, the record, `u`, `v`, the instance), without the normal, side and source id a [`Hit`] adds, which cost
/// the kernel reads and arithmetic a hit. The same values as the ray's [`Hit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HitCore {
    /// [`Hit::t`].
    pub t: f32,
    /// [`Hit::triangle_index`].
    pub triangle_index: u32,
    /// [`Hit::u`].
    pub u: f32,
    /// [`Hit::v`].
    pub v: f32,
    /// [`Hit::instance_index`].
    pub instance_index: Option<u32>,
}

impl Hit {
    /// The hit's core: what the lean hand-off gives for it.
    pub fn core(&self) -> HitCore {
        HitCore {
            t: self.t,
            triangle_index: self.triangle_index,
            u: self.u,
            v: self.v,
            instance_index: self.instance_index,
        }
    }
}

impl HitCore {
    /// The hit in lane `address` ([`lane_address`]) of `packets`, as [`Hit::in_lane`] gives it, without the rest.
    #[inline(always)]
    pub(crate) fn in_lane(address: u32, hit: TriangleHit, packets: &[TrianglePacket4]) -> HitCore {
        let triangle_index = lane_record(packets, address);
        HitCore { t: hit.t, triangle_index, u: hit.u, v: hit.v, instance_index: None }
    }
}

/// The geometric normal of a triangle record, `(v1 - v0) x (v2 - v0)` in f32: `e1 = v1 - v0`, `e2 = v2 - v0`
/// per axis, then `n_x = e1_y * e2_z - e1_z * e2_y`, `n_y = e1_z * e2_x - e1_x * e2_z`,
/// `n_z = e1_x * e2_y - e1_y * e2_x` (each product rounded, then the difference). Not normalized; zero for a
/// degenerate record.
pub fn geometric_normal(triangle: &PackedTriangle) -> [f32; 3] {
    let [v0, v1, v2] = &triangle.vertices;
    let e1 = [v1[0] - v0[0], v1[1] - v0[1], v1[2] - v0[2]];
    let e2 = [v2[0] - v0[0], v2[1] - v0[1], v2[2] - v0[2]];
    [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]]
}

/// Where the wide kernel found a hit: `PACKET_LANES * packet + lane` of the `triangle_packets` section (below
/// `2^30`, since `packet_count <= 2^28`, V10), turned into a [`Hit`] by [`Hit::in_lane`].
pub(crate) fn lane_address(packet: usize, lane: usize) -> u32 {
    (packet * PACKET_LANES + lane) as u32
}

/// The triangle record at lane address `address` ([`lane_address`]) of `packets`: a hit's tie key in the wide
/// kernels (`u32::MAX` past the end, which only a file that fails verification gives).
#[inline]
pub(crate) fn lane_record(packets: &[TrianglePacket4], address: u32) -> u32 {
    let (packet, lane) = (address as usize / PACKET_LANES, address as usize % PACKET_LANES);
    packets.get(packet).map_or(u32::MAX, |packet| packet.triangle_index[lane])
}

/// Receives traversal events. The default path uses `()`, whose empty methods compile away.
pub trait TraversalCounter {
    /// A node was visited (its children's boxes tested, or its triangles).
    fn node_visited(&mut self) {}
    /// A ray-triangle test was run.
    fn triangle_tested(&mut self) {}
}

impl TraversalCounter for () {}

/// Counts of the opt-in statistics mode, summed over the rays traced with it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalStats {
    /// Nodes visited.
    pub node_visits: u64,
    /// Ray-triangle tests.
    pub triangle_tests: u64,
}

impl TraversalCounter for TraversalStats {
    #[inline(always)]
    fn node_visited(&mut self) {
        self.node_visits += 1;
    }
    #[inline(always)]
    fn triangle_tested(&mut self) {
        self.triangle_tests += 1;
    }
}

/// Panics with a message naming `call` unless a batch's rays and results are as many (Embree's rule: a batch
/// call with mismatched buffers is a caller's bug, reported at once, never a partial trace).
#[track_caller]
pub(crate) fn same_length(call: &str, rays: usize, results: usize) {
    assert!(rays == results, "Tracer::{call}: {rays} rays but {results} result slots; pass slices of the same length");
}

/// Why a [`Hit`] cannot be one of a file's (what [`crate::Tracer::surface`] and the C API refuse): its record or
/// instance is not in the file, its instance does not place the record's mesh, or its `u`, `v` do not lie on a
/// triangle.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum ForeignHit {
    /// `triangle_index` is not below the file's record count.
    Triangle {
        /// The hit's record index.
        index: u32,
        /// The file's records.
        count: usize,
    },
    /// A one-level file's hit names an instance, or a two-level file's hit names none.
    Levels {
        /// Whether the file is two-level.
        two_level: bool,
    },
    /// `instance_index` is not below the file's instance count.
    Instance {
        /// The hit's instance.
        index: u32,
        /// The file's instances.
        count: usize,
    },
    /// The record is not in the mesh that the hit's instance places.
    NotInMesh {
        /// The hit's record index.
        triangle: u32,
        /// The hit's instance.
        instance: u32,
    },
    /// The barycentric coordinates are NaN or outside the triangle: every kernel's hit has `u >= 0`, `v >= 0`
    /// and `u + v <= 1` (within [`BARYCENTRIC_SLACK`] for the rounding of `u + v`).
    OffTriangle {
        /// The hit's `u`.
        u: f32,
        /// The hit's `v`.
        v: f32,
    },
}

/// How far above 1 a hit's `u + v` (summed in f32) may lie and still name a point of its triangle: `2^-20`.
/// A kernel's `u + v` exceeds 1 by at most a few units of `2^-24` (`format-spec/bvh-1.md` 11.1, "Accuracy").
pub const BARYCENTRIC_SLACK: f32 = 1.0 / 1_048_576.0;

/// Whether `(u, v)` names a point of the triangle: both at least 0 (either zero), `u + v <= 1 +`
/// [`BARYCENTRIC_SLACK`], neither NaN.
pub(crate) fn on_triangle(u: f32, v: f32) -> bool {
    u >= 0.0 && v >= 0.0 && u + v <= 1.0 + BARYCENTRIC_SLACK
}

impl std::fmt::Display for ForeignHit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            ForeignHit::Triangle { index, count } => {
                write!(f, "the hit's triangle index {index} is not below the file's {count} records")
            }
            ForeignHit::Levels { two_level: true } => {
                f.write_str("the file is two-level but the hit names no instance")
            }
            ForeignHit::Levels { two_level: false } => {
                f.write_str("the file is one-level but the hit names an instance")
            }
            ForeignHit::Instance { index, count } => {
                write!(f, "the hit's instance index {index} is not below the file's {count} instances")
            }
            ForeignHit::NotInMesh { triangle, instance } => {
                write!(f, "record {triangle} is not in the mesh that instance {instance} places")
            }
            ForeignHit::OffTriangle { u, v } => write!(
                f,
                "the hit's barycentric coordinates u = {u}, v = {v} are not on its triangle (u >= 0, v >= 0, u + v <= 1)"
            ),
        }
    }
}

impl std::error::Error for ForeignHit {}

/// The `each` callback of the batch calls that fill slices: ray `i`'s result into `slots[i]`.
pub(crate) fn slot_writer<T>(slots: &mut [T]) -> impl FnMut(usize, T) + '_ {
    move |i, result| {
        if let Some(slot) = slots.get_mut(i) {
            *slot = result;
        }
    }
}
