//! On-disk types of the GPU layout (format 1.4, `format-spec/bvh-1.md` 5.14-5.15): the compressed 8-wide nodes
//! of H. Ylitie, T. Karras, S. Laine, "Efficient Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs"
//! (HPG 2017, section 4: 80-byte nodes, child boxes quantized to 8 bits on a power-of-two grid anchored at the
//! node's origin), and the leaf triangles they reference, in leaf order with their vertices, so a compute shader
//! reads a triangle with one contiguous load and needs no index indirection until it reports the hit.
//!
//! The bit layout follows the paper: per slot a meta byte (inner child: `0b001` over `24 + slot`; leaf: its
//! triangle count in unary over its offset from the node's first triangle; empty: 0), an inner-child mask, the
//! first child node and the first triangle. Its traversal order (ray octants, highest hit bit first) is the
//! paper's and obvhs's; the file pins the placement of nodes and triangles further (5.14) so that a verifier can
//! check every reference in one pass.

/// Slots of a GPU node.
pub const GPU_WIDE: usize = 8;

/// Most triangles in one leaf: the meta byte's three unary count bits.
pub const GPU_MAX_LEAF_TRIANGLES: usize = 3;

/// Most triangles a node's leaves hold together: the meta byte's offsets, and the 24 low bits of a traversal's
/// triangle hit mask.
pub const GPU_MAX_NODE_TRIANGLES: usize = 24;

/// Deepest GPU node (the root has depth 0; rule V47): a traversal stack of this many (node group) entries never
/// overflows, since each level of the current path holds at most one.
pub const GPU_MAX_DEPTH: usize = 64;

/// Meta byte of an inner child in slot `s`: `0b001` in the top three bits, `24 + s` in the low five.
pub const fn inner_meta(slot: usize) -> u8 {
    0b0010_0000 | (24 + slot as u8)
}

/// Meta byte of a leaf of `count` triangles (1 to 3) at `offset` (below 24) from the node's first triangle.
pub const fn leaf_meta(offset: usize, count: usize) -> u8 {
    ((((1u32 << count) - 1) as u8) << 5) | offset as u8
}

/// One compressed 8-wide node (the `gpu_nodes` section, since 1.4), 80 bytes.
///
/// A slot's box is decoded per axis `a` as `origin[a] + q * 2^(exponents[a] - 127)` for its byte `q` of
/// `quantized_min` or `quantized_max`, evaluated in f32: the product is exact (an 8-bit integer times a power of
/// two in the normal range) and the sum rounds to nearest, so every reader, and every GPU, decodes the same
/// value; the writer chooses the bytes so that the decoded box contains the child's exact one (V48).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuNode {
    /// The grid's anchor (x, y, z).
    pub origin: [f32; 3],
    /// Per axis, the biased exponent of the grid step: the step is the f32 with these exponent bits and a zero
    /// mantissa, `2^(e - 127)`; 1 to 254.
    pub exponents: [u8; 3],
    /// Bit `s` set when slot `s` holds an inner child.
    pub inner_mask: u8,
    /// The inner children are nodes `child_base ..`, one per set bit of `inner_mask`, in slot order.
    pub child_base: u32,
    /// The leaves' triangles are GPU triangles `triangle_base + offset ..` (offsets in the meta bytes).
    pub triangle_base: u32,
    /// Per slot: 0 (empty), [`inner_meta`] or [`leaf_meta`].
    pub meta: [u8; GPU_WIDE],
    /// Per axis and slot, the box minimum's grid coordinate.
    pub quantized_min: [[u8; GPU_WIDE]; 3],
    /// Per axis and slot, the box maximum's grid coordinate.
    pub quantized_max: [[u8; GPU_WIDE]; 3],
}

/// What a slot of a [`GpuNode`] holds, decoded from its meta byte.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GpuSlot {
    /// Nothing (meta 0).
    Empty,
    /// An inner child: node `child_base + (set bits of inner_mask below the slot)`.
    Inner(u32),
    /// A leaf: GPU triangles `first .. first + count`.
    Leaf {
        /// The first triangle, absolute.
        first: u32,
        /// 1 to 3.
        count: u32,
    },
    /// A meta byte that is none of the above (V47 rejects it).
    Invalid,
}

impl GpuNode {
    /// A node with no children and a zero grid (origin 0, the smallest step): what an encoder starts from.
    pub const EMPTY: GpuNode = GpuNode {
        origin: [0.0; 3],
        exponents: [1; 3],
        inner_mask: 0,
        child_base: 0,
        triangle_base: 0,
        meta: [0; 8],
        quantized_min: [[0; 8]; 3],
        quantized_max: [[0; 8]; 3],
    };

    /// The grid step of `axis`: `2^(exponents[axis] - 127)`.
    pub fn scale(&self, axis: usize) -> f32 {
        f32::from_bits(u32::from(self.exponents[axis]) << 23)
    }

    /// The decoded grid coordinate `q` of `axis`: `origin + q * scale` in f32 (the product exact, one
    /// rounding), what the shader computes.
    pub fn decode(&self, axis: usize, q: u8) -> f32 {
        self.origin[axis] + f32::from(q) * self.scale(axis)
    }

    /// The decoded box of `slot`, `(min, max)`.
    pub fn slot_box(&self, slot: usize) -> ([f32; 3], [f32; 3]) {
        (
            std::array::from_fn(|a| self.decode(a, self.quantized_min[a][slot])),
            std::array::from_fn(|a| self.decode(a, self.quantized_max[a][slot])),
        )
    }

    /// What `slot` holds.
    pub fn slot(&self, slot: usize) -> GpuSlot {
        let meta = self.meta[slot];
        if meta == 0 {
            return GpuSlot::Empty;
        }
        if meta == inner_meta(slot) {
            let below = u32::from(self.inner_mask) & ((1u32 << slot) - 1);
            return GpuSlot::Inner(self.child_base.wrapping_add(below.count_ones()));
        }
        let (unary, offset) = (meta >> 5, u32::from(meta & 31));
        let count = match unary {
            0b001 => 1,
            0b011 => 2,
            0b111 => 3,
            _ => return GpuSlot::Invalid,
        };
        if offset + count > GPU_MAX_NODE_TRIANGLES as u32 {
            return GpuSlot::Invalid;
        }
        GpuSlot::Leaf { first: self.triangle_base.wrapping_add(offset), count }
    }
}

/// One leaf triangle of the GPU layout (the `gpu_triangles` section, since 1.4), 40 bytes: the vertices of
/// record `triangle_index` of the `triangles` section, bit for bit, in leaf order.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuTriangle {
    /// `v0`, `v1`, `v2`, each `(x, y, z)`.
    pub vertices: [[f32; 3]; 3],
    /// The record in the `triangles` section (and in `triangle_ids`) whose vertices these are.
    pub triangle_index: u32,
}

const _: () = assert!(size_of::<GpuNode>() == 80);
const _: () = assert!(size_of::<GpuTriangle>() == 40);

crate::format::plain_data::plain_data! {
    GpuNode { [f32; 3], [u8; 3], u8, u32, u32, [u8; 8], [[u8; 8]; 3], [[u8; 8]; 3] }
    GpuTriangle { [[f32; 3]; 3], u32 }
}
