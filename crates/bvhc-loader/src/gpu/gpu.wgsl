// bvhc's GPU traversal kernel for the GPU sections of `.bvh` format 1.4 (format-spec/bvh-1.md 5.14, 5.15, 11.4):
// closest hit and any hit of a batch of rays through compressed 8-wide nodes (Ylitie, Karras, Laine, "Efficient
// Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", HPG 2017) with the robust slab test of the CPU
// kernels (Ize 2013) and the watertight triangle test (Woop, Benthin, Wald 2013) in f32 only.
//
// The loader crate's `GpuLayoutTracer` runs these steps on the CPU; tests compare the two and the CPU kernel.
//
// Bindings (group 0), one invocation a ray, 64 a workgroup, entry points `closest_hit` and `any_hit`:
//   0  gpu_nodes      storage, read        the `gpu_nodes` section's bytes (80 bytes a node, as array<vec4<u32>>)
//   1  gpu_triangles  storage, read        the `gpu_triangles` section's bytes (40 bytes a triangle, array<vec2<u32>>)
//   2  rays           storage, read        `Ray`s (32 bytes each); t_max must be finite (use 3.4e38 for "none")
//   3  hits           storage, read_write  one `HitRecord` (16 bytes) per ray; `triangle` = 0xffffffff: no hit,
//                                          and with t = -1: trace this ray on the CPU (an ill-conditioned hit)
//   4  params         uniform              `Params`: how many rays
// A hit names the record of the `triangles` section (its source id is `triangle_ids[triangle]`); `t`, `u`, `v` are
// those of the CPU kernels (hit point `(1 - u - v) v0 + u v1 + v v2`). Any hit writes the first hit it finds.

struct Ray {
    origin: vec3<f32>,
    t_min: f32,
    direction: vec3<f32>,
    t_max: f32,
}

struct HitRecord {
    t: f32,
    u: f32,
    v: f32,
    triangle: u32,
}

struct Params {
    ray_count: u32,
    // 1 when the triangles section has SPLIT_REFERENCES: hits at one t are then ordered by coordinates.
    split_references: u32,
    // The tree's part in the reach (format-spec/bvh-1.md 11.2): 2^-11 times the largest side of the root's boxes.
    reach_scale: f32,
    // 1 with split_references when binding 5 holds the records' source ids: equal coordinates are then ordered
    // by id.
    tie_by_ids: u32,
}

@group(0) @binding(0) var<storage, read> gpu_nodes: array<vec4<u32>>;
@group(0) @binding(1) var<storage, read> gpu_triangles: array<vec2<u32>>;
@group(0) @binding(2) var<storage, read> rays: array<Ray>;
@group(0) @binding(3) var<storage, read_write> hits: array<HitRecord>;
@group(0) @binding(4) var<uniform> params: Params;
@group(0) @binding(5) var<storage, read> triangle_ids: array<u32>;

const NO_HIT: u32 = 0xffffffffu;
// Slab exit distances are padded by 1 + 2^-19: Ize's bound for three correctly rounded operations, widened for
// WGSL's division (2.5 ulp) and one more rounding.
const EXIT_PADDING: f32 = 1.0000019073486328;
// Boxes are culled beyond the reach of the closest hit so far (or t_max), as on the CPU (11.2):
// t (1 + 2^-11) + reach_scale |sz|.
const REACH_SCALE: f32 = 1.00048828125;
// 2^-18: an edge function above 2^-18 rho (rho + R) has the sign exact arithmetic gives it (11.2, the box
// condition's shortcut).
const EXACT_SIGNS: f32 = 3.814697265625e-06;
const MIN_NORMAL: f32 = 1.1754943508222875e-38;
const F32_MAX: f32 = 3.4028234663852886e38;
const STACK_SIZE: u32 = 64u;
// 11.1 step 5: a hit is ill-conditioned when |det| < extent / 64, or extent < 2^-100.
const ILL_CONDITIONED: f32 = 0.015625;
const TINY_EXTENT: f32 = 7.888609052210118e-31;
// Widens an ill-conditioned candidate's depth range over the rounding of its depths (2^-20).
const DEPTH_SLACK: f32 = 9.5367431640625e-07;
const INNER_MASK: u32 = 0xff000000u;

// A ray with what both tests need, computed once (as the CPU's PreparedRay).
struct Prepared {
    origin: vec3<f32>,
    inverse: vec3<f32>,
    exit_inverse: vec3<f32>,
    negative: vec3<bool>,
    flat: vec3<bool>,
    t_min: f32,
    k: vec3<u32>,
    shear: vec3<f32>,
}

fn prepare(ray: Ray) -> Prepared {
    var p: Prepared;
    let d = ray.direction;
    let a = abs(d);
    var kz = 2u;
    if (a.x >= a.y && a.x >= a.z) {
        kz = 0u;
    } else if (a.y >= a.z) {
        kz = 1u;
    }
    var kx = (kz + 1u) % 3u;
    var ky = (kz + 2u) % 3u;
    if (d[kz] < 0.0) {
        let swap = kx;
        kx = ky;
        ky = swap;
    }
    p.origin = ray.origin;
    p.flat = a < vec3<f32>(MIN_NORMAL);
    let safe = select(d, vec3<f32>(1.0), p.flat);
    p.inverse = vec3<f32>(1.0) / safe;
    p.exit_inverse = p.inverse * EXIT_PADDING;
    p.negative = (bitcast<vec3<u32>>(d) >> vec3<u32>(31u)) == vec3<u32>(1u);
    p.t_min = ray.t_min;
    p.k = vec3<u32>(kx, ky, kz);
    p.shear = vec3<f32>(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
    return p;
}

// `inv`: bit 2, 1, 0 set when the direction's x, y, z is >= 0.
fn octant_inverse(d: vec3<f32>) -> u32 {
    return select(0u, 4u, d.x >= 0.0) | select(0u, 2u, d.y >= 0.0) | select(0u, 1u, d.z >= 0.0);
}

fn byte_of(word: u32, index: u32) -> u32 {
    return (word >> ((index & 3u) * 8u)) & 0xffu;
}

// Byte `slot` of an 8-byte row stored as two words.
fn row_byte(low: u32, high: u32, slot: u32) -> u32 {
    return byte_of(select(low, high, slot >= 4u), slot);
}

// The hit bits of node `n` within [t_min, far] (inner children at 24 + (slot ^ inv), leaves' triangles at their
// offsets), the node's child base, triangle base and inner mask.
fn visit_node(n: u32, ray: Prepared, inv: u32, far: f32) -> vec4<u32> {
    let w0 = gpu_nodes[n * 5u];
    let w1 = gpu_nodes[n * 5u + 1u];
    let w2 = gpu_nodes[n * 5u + 2u];
    let w3 = gpu_nodes[n * 5u + 3u];
    let w4 = gpu_nodes[n * 5u + 4u];
    let origin = bitcast<vec3<f32>>(w0.xyz);
    let scale = bitcast<vec3<f32>>(vec3<u32>(byte_of(w0.w, 0u), byte_of(w0.w, 1u), byte_of(w0.w, 2u)) << vec3<u32>(23u));
    var hits = 0u;
    for (var slot = 0u; slot < 8u; slot++) {
        let slot_meta = row_byte(w1.z, w1.w, slot);
        if (slot_meta == 0u) {
            continue;
        }
        let q_min = vec3<f32>(vec3<u32>(row_byte(w2.x, w2.y, slot), row_byte(w2.z, w2.w, slot), row_byte(w3.x, w3.y, slot)));
        let q_max = vec3<f32>(vec3<u32>(row_byte(w3.z, w3.w, slot), row_byte(w4.x, w4.y, slot), row_byte(w4.z, w4.w, slot)));
        // Exact products (a byte times a power of two), one rounding each.
        let lo = origin + q_min * scale;
        let hi = origin + q_max * scale;
        var near = ray.t_min;
        var far_slot = far;
        var inside = true;
        for (var axis = 0u; axis < 3u; axis++) {
            let o = ray.origin[axis];
            if (ray.flat[axis]) {
                // A (near) zero direction component: the slab holds the origin or nothing.
                inside = inside && o >= lo[axis] && o <= hi[axis];
                continue;
            }
            let entry = select(lo[axis], hi[axis], ray.negative[axis]);
            let exit = select(hi[axis], lo[axis], ray.negative[axis]);
            let t_entry = (entry - o) * ray.inverse[axis];
            let t_exit = (exit - o) * ray.exit_inverse[axis];
            near = select(near, t_entry, t_entry > near);
            far_slot = select(far_slot, t_exit, t_exit < far_slot);
        }
        if (inside && near <= far_slot) {
            let is_inner = (slot_meta & 0x18u) == 0x18u;
            let bit_index = select(slot_meta & 31u, (slot_meta & 31u) ^ inv, is_inner);
            hits |= (slot_meta >> 5u) << bit_index;
        }
    }
    return vec4<u32>(hits, w1.x, w1.y, w0.w >> 24u);
}

// A 48-bit integer as (bits 24-47, bits 0-23): the exact product of two significands below 2^24, from 12-bit
// halves (every partial sum stays below 2^26).
fn product48(a: u32, b: u32) -> vec2<u32> {
    let ah = a >> 12u;
    let al = a & 0xfffu;
    let bh = b >> 12u;
    let bl = b & 0xfffu;
    let middle = ah * bl + al * bh;
    let low = al * bl + ((middle & 0xfffu) << 12u);
    return vec2<u32>(ah * bh + (middle >> 12u) + (low >> 24u), low & 0xffffffu);
}

// A nonzero 48-bit integer shifted left until bit 47 is set: (bits 24-47, bits 0-23, the shift).
fn normalize48(p: vec2<u32>) -> vec3<u32> {
    var high = p.x;
    var low = p.y;
    var shift = 0u;
    if (high == 0u) {
        high = low;
        low = 0u;
        shift = 24u;
    }
    let s = countLeadingZeros(high) - 8u;
    if (s > 0u) {
        high = ((high << s) | (low >> (24u - s))) & 0xffffffu;
        low = (low << s) & 0xffffffu;
    }
    return vec3<u32>(high, low, shift + s);
}

// A finite f32 x as (significand m below 2^24, exponent e) with x = +-m 2^e.
fn split(x: f32) -> vec2<i32> {
    let bits = bitcast<u32>(x);
    let field = (bits >> 23u) & 0xffu;
    if (field == 0u) {
        return vec2<i32>(i32(bits & 0x7fffffu), -149);
    }
    return vec2<i32>(i32((bits & 0x7fffffu) | 0x800000u), i32(field) - 150);
}

// a b - c d rounded once to f32, for products whose f32 roundings are equal and normal: what the CPU kernels'
// f64 recomputation gives an edge function that is exactly 0 in f32 (11.1), and the loader's CPU model computes
// (watertight.rs, exact_product_difference), here with integers since WGSL has no f64. The exact products then
// differ by at most an ulp of their rounding, so aligned on the finer one's last bit their difference fits in
// 27 bits. Below the normal range the result is +-2^-126 with the exact sign (a subnormal could be flushed).
fn exact_product_difference(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let sa = split(a);
    let sb = split(b);
    let sc = split(c);
    let sd = split(d);
    let n1 = normalize48(product48(u32(sa.x), u32(sb.x)));
    let n2 = normalize48(product48(u32(sc.x), u32(sd.x)));
    var e1 = sa.y + sb.y - i32(n1.z);
    var e2 = sc.y + sd.y - i32(n2.z);
    var h1 = n1.x;
    var l1 = n1.y;
    var h2 = n2.x;
    var l2 = n2.y;
    if (abs(e1 - e2) > 1) {
        return 0.0; // not reached: equal roundings put the leading bits at most one place apart
    }
    if (e1 > e2) {
        h1 = (h1 << 1u) | (l1 >> 23u);
        l1 = (l1 << 1u) & 0xffffffu;
    } else if (e2 > e1) {
        h2 = (h2 << 1u) | (l2 >> 23u);
        l2 = (l2 << 1u) & 0xffffffu;
    }
    let high = i32(h1) - i32(h2);
    if (abs(high) > 8) {
        return 0.0; // not reached, as above
    }
    let difference = high * 16777216 + (i32(l1) - i32(l2));
    if (difference == 0) {
        return 0.0;
    }
    // The products' common sign flips the difference's.
    let negative = (difference < 0) != (((bitcast<u32>(a) ^ bitcast<u32>(b)) >> 31u) == 1u);
    var q = u32(abs(difference));
    var exponent = min(e1, e2);
    let top = 31u - countLeadingZeros(q);
    if (top > 23u) {
        // To 24 significant bits, to nearest, ties to even.
        let shift = top - 23u;
        let rest = q & ((1u << shift) - 1u);
        let half = 1u << (shift - 1u);
        q = q >> shift;
        exponent += i32(shift);
        if (rest > half || (rest == half && (q & 1u) == 1u)) {
            q += 1u;
        }
        if (q == 0x1000000u) {
            q = 0x800000u;
            exponent += 1;
        }
    } else {
        q = q << (23u - top);
        exponent -= i32(23u - top);
    }
    let sign = select(0u, 0x80000000u, negative);
    let biased = exponent + 150;
    if (biased <= 0) {
        return bitcast<f32>(sign | 0x800000u);
    }
    return bitcast<f32>(sign | (u32(biased) << 23u) | (q & 0x7fffffu));
}

// The edge function a b - c d: the f32 difference of the two rounded products, whose sign is exact when they
// differ (rounding is monotone; a compiler that fuses the subtraction keeps that sign), and where they are
// equal, so the f32 value is 0, the exact value (exact_product_difference) when the products are normal.
fn edge_function(a: f32, b: f32, c: f32, d: f32) -> f32 {
    let p = a * b;
    let q = c * d;
    let field = (bitcast<u32>(p) >> 23u) & 0xffu;
    if (p == q && field != 0u && field != 255u) {
        return exact_product_difference(a, b, c, d);
    }
    return p - q;
}

// The watertight test of GPU triangle `g` in f32: (t, u, v) and w = 1 if it hits within [t_min, t_max]; w = 2 for
// an ill-conditioned hit (see below). Every
// edge function has its exact sign (edge_function), as with the CPU kernels' f64 recomputation, so a ray through
// a shared edge hits at least one of its triangles and a ray just outside a silhouette misses.
fn intersect_triangle(g: u32, ray: Prepared, t_max: f32) -> vec4<f32> {
    let r0 = gpu_triangles[g * 5u];
    let r1 = gpu_triangles[g * 5u + 1u];
    let r2 = gpu_triangles[g * 5u + 2u];
    let r3 = gpu_triangles[g * 5u + 3u];
    let r4 = gpu_triangles[g * 5u + 4u];
    let v0 = bitcast<vec3<f32>>(vec3<u32>(r0.x, r0.y, r1.x));
    let v1 = bitcast<vec3<f32>>(vec3<u32>(r1.y, r2.x, r2.y));
    let v2 = bitcast<vec3<f32>>(vec3<u32>(r3.x, r3.y, r4.x));
    let a3 = v0 - ray.origin;
    let b3 = v1 - ray.origin;
    let c3 = v2 - ray.origin;
    let k = ray.k;
    let az = a3[k.z];
    let bz = b3[k.z];
    let cz = c3[k.z];
    let ax = a3[k.x] - ray.shear.x * az;
    let ay = a3[k.y] - ray.shear.y * az;
    let bx = b3[k.x] - ray.shear.x * bz;
    let by = b3[k.y] - ray.shear.y * bz;
    let cx = c3[k.x] - ray.shear.x * cz;
    let cy = c3[k.y] - ray.shear.y * cz;
    let e_u = edge_function(cx, by, cy, bx);
    let e_v = edge_function(ax, cy, ay, cx);
    let e_w = edge_function(bx, ay, by, ax);
    let miss = vec4<f32>(0.0, 0.0, 0.0, 0.0);
    let negative = e_u < 0.0 || e_v < 0.0 || e_w < 0.0;
    let positive = e_u > 0.0 || e_v > 0.0 || e_w > 0.0;
    if (negative && positive) {
        return miss;
    }
    let det = e_u + e_v + e_w;
    if (det == 0.0) {
        return miss;
    }
    // An ill-conditioned hit (11.1 step 5: a needle, a sliver, a ray nearly in the plane) gets its exact t, u, v
    // on the CPU, which WGSL's f32 cannot compute: it is not taken here; w = 2 and x, y the lowest and highest t it
    // can have (the vertices' depths along the ray, widened over their rounding), for trace's decision.
    let rho = max(max(max(abs(ax), abs(ay)), max(abs(bx), abs(by))), max(abs(cx), abs(cy)));
    let extent = rho * (rho + (max(max(az, bz), cz) - min(min(az, bz), cz)));
    if (abs(det) < extent * ILL_CONDITIONED || extent < TINY_EXTENT) {
        let z0 = ray.shear.z * az;
        let z1 = ray.shear.z * bz;
        let z2 = ray.shear.z * cz;
        let low = min(min(z0, z1), z2);
        let high = max(max(z0, z1), z2);
        return vec4<f32>(low - abs(low) * DEPTH_SLACK, high + abs(high) * DEPTH_SLACK, 0.0, 2.0);
    }
    let t = (e_u * (ray.shear.z * az) + e_v * (ray.shear.z * bz) + e_w * (ray.shear.z * cz)) / det;
    if (!(t >= ray.t_min && t <= t_max)) {
        return miss;
    }
    // The box condition (11.1): a hit whose edge functions are all clear of their rounding is a hit of the exact
    // ray inside the triangle, which meets it; another (a ray within rounding of an edge) is left to the CPU, which
    // tests the record's box with its exact arithmetic: w = 2, both bounds t.
    let smallest = min(min(abs(e_u), abs(e_v)), abs(e_w));
    let depth = max(max(abs(az), abs(bz)), abs(cz));
    if (!(smallest > rho * (rho + depth) * EXACT_SIGNS && t <= F32_MAX)) {
        return vec4<f32>(t, t, 0.0, 2.0);
    }
    let inverse_det = 1.0 / det;
    return vec4<f32>(t, e_v * inverse_det, e_w * inverse_det, 1.0);
}

// One ray's walk (Ylitie et al. 2017, Algorithm 1, triangles tested as soon as their node is visited): the hit
// record, for any hit the first found.
// Whether, of two hits at one t, the one on GPU triangle g (record `triangle`) comes before the one on best_g
// (record `best`): the lower record, or with split references the lower coordinates (nine bit patterns compared
// as unsigned integers in order) and then the lower source id, as format-spec/bvh-1.md 11.1 orders them.
fn precedes_at_tie(g: u32, triangle: u32, best_g: u32, best: u32) -> bool {
    if (params.split_references == 0u) {
        return triangle < best;
    }
    for (var k = 0u; k < 9u; k += 1u) {
        let a = gpu_triangles[g * 5u + k / 2u][k % 2u];
        let b = gpu_triangles[best_g * 5u + k / 2u][k % 2u];
        if (a != b) {
            return a < b;
        }
    }
    if (params.tie_by_ids != 0u) {
        return triangle_ids[triangle] < triangle_ids[best];
    }
    return false;
}

fn trace(ray_in: Ray, any_hit: bool) -> HitRecord {
    var record = HitRecord(0.0, 0.0, 0.0, NO_HIT);
    let node_count = arrayLength(&gpu_nodes) / 5u;
    if (node_count == 0u) {
        return record;
    }
    let ray = prepare(ray_in);
    let inv = octant_inverse(ray_in.direction);
    var best_t = ray_in.t_max;
    var best_g = 0u;
    // The lowest t an ill-conditioned candidate could have (within [t_min, ...]); above t_max: none met.
    var ill_low = F32_MAX;
    var ill = false;
    var stack: array<vec2<u32>, STACK_SIZE>;
    var stack_len = 0u;
    var visits = 0u;
    // The root as the only inner child (slot 0) of a group based at node 0.
    var node_group = vec2<u32>(0u, (1u << (24u + inv)) | 1u);
    loop {
        var triangle_group = vec2<u32>(0u, 0u);
        if ((node_group.y & INNER_MASK) != 0u) {
            let bit = 31u - countLeadingZeros(node_group.y);
            node_group.y &= ~(1u << bit);
            let slot = (bit - 24u) ^ inv;
            let index = node_group.x + countOneBits(node_group.y & 0xffu & ((1u << slot) - 1u));
            if ((node_group.y & INNER_MASK) != 0u) {
                if (stack_len == STACK_SIZE) {
                    break;
                }
                stack[stack_len] = node_group;
                stack_len += 1u;
            }
            visits += 1u;
            if (index >= node_count || visits > node_count) {
                break;
            }
            // Culled beyond the reach of the closest hit so far (or t_max), as on the CPU. Kept finite: WGSL may
            // assume that no infinity occurs.
            let reach = best_t * REACH_SCALE + params.reach_scale * abs(ray.shear.z);
            let far = select(F32_MAX, reach, reach <= F32_MAX);
            let visited = visit_node(index, ray, inv, far);
            node_group = vec2<u32>(visited.y, (visited.x & INNER_MASK) | visited.w);
            triangle_group = vec2<u32>(visited.z, visited.x & ~INNER_MASK);
        }
        while (triangle_group.y != 0u) {
            let bit = 31u - countLeadingZeros(triangle_group.y);
            triangle_group.y &= ~(1u << bit);
            let g = triangle_group.x + bit;
            let hit = intersect_triangle(g, ray, best_t);
            if (hit.w == 2.0) {
                if (hit.y >= ray_in.t_min) {
                    ill = true;
                    ill_low = min(ill_low, hit.x);
                }
            } else if (hit.w != 0.0) {
                // Of two hits at one t the first in spec 11.1's order is kept (the lower record, or with split
                // references the lower coordinates).
                let triangle = gpu_triangles[g * 5u + 4u].y;
                if (any_hit || hit.x < best_t || record.triangle == NO_HIT
                    || (hit.x == best_t && precedes_at_tie(g, triangle, best_g, record.triangle))) {
                    best_t = hit.x;
                    best_g = g;
                    record = HitRecord(hit.x, hit.y, hit.z, triangle);
                    if (any_hit) {
                        return record;
                    }
                }
            }
        }
        if ((node_group.y & INNER_MASK) == 0u) {
            if (stack_len == 0u) {
                break;
            }
            stack_len -= 1u;
            node_group = stack[stack_len];
        }
    }
    // An ill-conditioned candidate that could be the closest hit (or, for any hit, the only one): the host
    // traces the ray on the CPU (GPU_REFINE).
    if (ill && ill_low <= best_t) {
        return HitRecord(-1.0, 0.0, 0.0, NO_HIT);
    }
    return record;
}

@compute @workgroup_size(64)
fn closest_hit(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x < params.ray_count) {
        hits[id.x] = trace(rays[id.x], false);
    }
}

@compute @workgroup_size(64)
fn any_hit(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x < params.ray_count) {
        hits[id.x] = trace(rays[id.x], true);
    }
}
