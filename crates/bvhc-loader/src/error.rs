//! Errors of the loader: a broken validity rule (numbered as in `format-spec/bvh-1.md`), or a host problem.

use std::fmt;
use std::path::PathBuf;

/// The validity rules of major version 1, numbered as in the spec (V1, V2, ...).
///
/// V1-V10 are structural and checked by every open; V11-V53 are checked by `BvhView::verify` (the rules of a
/// section kind only when a file has it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Rule {
    /// V1: at least 64 bytes, starting with the magic.
    Magic,
    /// V2: major version 1.
    MajorVersion,
    /// V3: `file_byte_len` equals the real length.
    FileByteLen,
    /// V4: the section table has a valid entry size and lies within the file.
    SectionTable,
    /// V5: sections are 64-byte aligned, inside the file, after the table, ascending and disjoint.
    SectionPlacement,
    /// V6: `section_byte_len == element_count * element_byte_len`, `element_byte_len >= 1`.
    SectionSize,
    /// V7: no unknown section kind is marked required.
    UnknownRequiredSection,
    /// V8: each known kind at most once; nodes and triangles exactly once; the wide sections together, and
    /// only in files of 1.1 or later.
    SectionMultiplicity,
    /// V9: known kinds have their element size and flags.
    SectionKindLayout,
    /// V10: element counts agree with each other and fit in u32.
    Counts,
    /// V11: the header checksum matches.
    HeaderChecksum,
    /// V12: every section checksum matches.
    SectionChecksum,
    /// V13: reserved fields and padding bytes are zero.
    ReservedZero,
    /// V14: inner nodes reference child pairs after themselves; every node but the root has exactly one parent.
    TreeShape,
    /// V15: leaves, in depth-first order, cover the triangles section consecutively and exactly.
    LeafPartition,
    /// V16: node boxes are finite with min <= max.
    NodeBox,
    /// V17: child boxes lie inside their parent's box.
    ChildInParent,
    /// V18: triangle vertices are finite.
    TriangleFinite,
    /// V19: a leaf's triangles lie inside its box.
    TriangleInLeaf,
    /// V20: no node deeper than `MAX_DEPTH`.
    Depth,
    /// V21: source ranges are non-empty, ascending, disjoint and do not overflow.
    SourceTable,
    /// V22: with a source table, every triangle id lies in one of its ranges.
    TriangleIdRange,
    /// V23: metadata is UTF-8 text without a byte order mark or NUL byte, holding one JSON object.
    Metadata,
    /// V24: without `SPLIT_REFERENCES`, triangle ids are distinct.
    RepeatedId,
    /// V25: with `SPLIT_REFERENCES`, the leaves that reference a triangle cover all of it.
    SplitCoverage,
    /// V26: every source range's `file_index` names an entry of the metadata's `inputs` (0 without them).
    FileIndex,
    /// V27: no metadata `inputs[].file_name` is an absolute path.
    AbsoluteFileName,
    /// V28: the metadata's `format_version` equals the header's version.
    FormatVersion,
    /// V29: wide node slots are well formed (references encoded and in range, children after their parent,
    /// occupied slots first, empty slots with the empty box, enough children).
    WideSlots,
    /// V30: every wide node but the root has exactly one parent slot, and none is deeper than `MAX_DEPTH`.
    WideTreeShape,
    /// V31: every triangle packet is in exactly one leaf reference.
    PacketPartition,
    /// V32: occupied slot boxes are finite with min <= max and lie inside their parent's box.
    WideBox,
    /// V33: packet lanes are well formed: used lanes first, each equal bit for bit to the triangle it indexes.
    PacketLanes,
    /// V34: every triangle is in exactly one packet lane.
    LaneCoverage,
    /// V35: a lane's triangle lies inside its leaf slot's box (with `SPLIT_REFERENCES`: overlaps it, and the
    /// wide leaves of a triangle's references cover it).
    LaneInLeaf,
    /// V36: the metadata's counts (`wide`, `triangles`) are the file's.
    MetadataCounts,
    /// V37: the metadata's costs (`cost`, `wide.cost`) are the file's, recomputed.
    MetadataCost,
    /// V38: the metadata's `build` object agrees with the sections and the leaves.
    MetadataBuild,
    /// V39: the metadata's `choice` kept the first candidate of lowest cost, and that is the file's cost.
    MetadataChoice,
    /// V40: source vertex indices agree with the vertices: one source vertex is one point wherever its primitive
    /// names it, and a triangle's references name the same vertices.
    SourceVertices,
    /// V41: in a two-level file, the meshes tile the nodes, triangles and wide sections in order, each with a
    /// one-level file's counts, and each mesh's ranges obey the one-level tree rules.
    MeshTable,
    /// V42: every instance names a mesh, and its transforms are finite, invertible and each other's inverse.
    InstanceTransform,
    /// V43: the top tree is a binary tree (V14, V16, V17, V20) whose leaves hold one instance each, every
    /// instance in exactly one leaf.
    TopTree,
    /// V44: a top leaf's box contains its instance's mesh root box mapped to world space.
    InstanceBox,
    /// V45: every mesh is placed by at least one instance.
    MeshPlaced,
    /// V46: the wide top tree is well formed, every instance in exactly one leaf slot, boxes conservative.
    TopWideTree,
    /// V47: the GPU nodes form one tree laid out breadth first, with meta bytes that agree with the inner masks
    /// and leaves that tile the GPU triangles, no deeper than 64.
    GpuTreeShape,
    /// V48: every decoded GPU slot box is finite, ordered, free of subnormals and contains the decoded boxes of
    /// its child node's slots.
    GpuBox,
    /// V49: every GPU triangle repeats its record's vertices, and every triangle is reachable (exactly once
    /// without split references).
    GpuTriangles,
    /// V50: every GPU leaf's triangles lie inside its decoded box (with split references: overlap it, and the
    /// leaves of a triangle cover it).
    GpuLeafBox,
    /// V51: a file of a minor version this reader knows has the lowest minor version its sections need.
    LowestMinor,
    /// V52: every `triangle_flags` element sets only the bits the file's minor version defines.
    TriangleFlagBits,
    /// V53: the records of one triangle (its references, or the records of one id) have the same flags.
    TriangleFlagsAgree,
}

impl Rule {
    /// Every rule, in spec order.
    pub const ALL: [Rule; 53] = [
        Rule::Magic,
        Rule::MajorVersion,
        Rule::FileByteLen,
        Rule::SectionTable,
        Rule::SectionPlacement,
        Rule::SectionSize,
        Rule::UnknownRequiredSection,
        Rule::SectionMultiplicity,
        Rule::SectionKindLayout,
        Rule::Counts,
        Rule::HeaderChecksum,
        Rule::SectionChecksum,
        Rule::ReservedZero,
        Rule::TreeShape,
        Rule::LeafPartition,
        Rule::NodeBox,
        Rule::ChildInParent,
        Rule::TriangleFinite,
        Rule::TriangleInLeaf,
        Rule::Depth,
        Rule::SourceTable,
        Rule::TriangleIdRange,
        Rule::Metadata,
        Rule::RepeatedId,
        Rule::SplitCoverage,
        Rule::FileIndex,
        Rule::AbsoluteFileName,
        Rule::FormatVersion,
        Rule::WideSlots,
        Rule::WideTreeShape,
        Rule::PacketPartition,
        Rule::WideBox,
        Rule::PacketLanes,
        Rule::LaneCoverage,
        Rule::LaneInLeaf,
        Rule::MetadataCounts,
        Rule::MetadataCost,
        Rule::MetadataBuild,
        Rule::MetadataChoice,
        Rule::SourceVertices,
        Rule::MeshTable,
        Rule::InstanceTransform,
        Rule::TopTree,
        Rule::InstanceBox,
        Rule::MeshPlaced,
        Rule::TopWideTree,
        Rule::GpuTreeShape,
        Rule::GpuBox,
        Rule::GpuTriangles,
        Rule::GpuLeafBox,
        Rule::LowestMinor,
        Rule::TriangleFlagBits,
        Rule::TriangleFlagsAgree,
    ];

    /// The rule's number in the spec (1 for V1).
    pub fn number(self) -> u32 {
        Rule::ALL.iter().position(|&r| r == self).map_or(0, |i| i as u32 + 1)
    }

    /// Whether every open checks this rule (V1-V10), rather than only `BvhView::verify`.
    pub fn is_structural(self) -> bool {
        self.number() <= 10
    }
}

impl fmt::Display for Rule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "V{}", self.number())
    }
}

/// A broken validity rule and where it broke.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Violation {
    /// The rule.
    pub rule: Rule,
    /// Where and how, e.g. `node 1234: child 98765 out of range (node_count 5000)`.
    pub detail: String,
}

impl fmt::Display for Violation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.rule, self.detail)
    }
}

impl std::error::Error for Violation {}

/// Everything that can go wrong when opening, verifying or writing a `.bvh` file.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The bytes break a validity rule.
    Invalid(Violation),
    /// The byte buffer does not start at a 4-byte-aligned address, so sections cannot be viewed in place.
    Misaligned {
        /// The buffer's address.
        address: usize,
    },
    /// The host is big-endian: the file's little-endian arrays cannot be viewed in place.
    BigEndianHost,
    /// Reading or writing a file failed.
    Io {
        /// The file.
        path: PathBuf,
        /// The cause.
        source: std::io::Error,
    },
    /// The allocator refused memory that reading or writing needs (the system's memory, or an address-space or
    /// other limit of the process): an error the caller can report, rather than the abort of a failed
    /// allocation.
    OutOfMemory {
        /// What the memory was for, e.g. `the file's bytes`.
        what: String,
        /// The size asked for.
        bytes: u64,
    },
    /// The data handed to the writer cannot be stored (too many elements for u32 indices, and similar).
    Unwritable(String),
    /// A refit the file cannot take ([`crate::BvhFile::refit_triangles`]): the file's kind, the positions' count,
    /// a coordinate (naming the record), a box the GPU layout cannot encode (naming the node).
    Refit(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Invalid(violation) => write!(f, "invalid .bvh file: {violation}"),
            Error::Misaligned { address } => write!(
                f,
                "the byte buffer starts at address {address:#x}, which is not 4-byte aligned; copy it with \
                 BvhFile::from_bytes or align it"
            ),
            Error::BigEndianHost => write!(
                f,
                "this host is big-endian; .bvh files are little-endian and are only viewed in place on little-endian \
                 hosts"
            ),
            Error::Io { path, source } => write!(f, "{}: {source}", path.display()),
            Error::OutOfMemory { what, bytes } => {
                write!(f, "out of memory: {what} needs {bytes} bytes, which the system refused")
            }
            Error::Unwritable(why) => write!(f, "cannot write .bvh file: {why}"),
            Error::Refit(why) => write!(f, "cannot refit .bvh file: {why}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Invalid(violation) => Some(violation),
            Error::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

impl From<Violation> for Error {
    fn from(violation: Violation) -> Error {
        Error::Invalid(violation)
    }
}

impl Error {
    /// The message for this error on the file at `path`: the error itself where it names the file already (a
    /// file that cannot be read), else prefixed with the path.
    pub fn for_file(&self, path: &std::path::Path) -> String {
        match self {
            Error::Io { .. } => self.to_string(),
            _ => format!("{}: {self}", path.display()),
        }
    }

    /// The broken rule, if this error is one.
    pub fn rule(&self) -> Option<Rule> {
        match self {
            Error::Invalid(v) => Some(v.rule),
            _ => None,
        }
    }
}

/// Shorthand for a rule violation.
pub(crate) fn violation(rule: Rule, detail: impl Into<String>) -> Violation {
    Violation { rule, detail: detail.into() }
}
