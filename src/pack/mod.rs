//! The pack stage: the leaf layout's trees in the file's layout. [`pack`] flattens the binary tree into the
//! nodes and triangles sections; [`pack_wide`] lays the wide tree out as the wide sections over those triangles,
//! [`pack_gpu`] the GPU's collapse as the compressed GPU sections (format 1.4). The nodes are encoded by the
//! loader's encoders (`WideNode8::set_slot`, `GpuNode::encode_slot_boxes`), beside their decoders.

mod binary;
mod gpu;
mod wide;

pub use binary::{PackedTree, RecordCursor, pack};
pub use gpu::{GpuLayout, pack_gpu};
pub use wide::pack_wide;
