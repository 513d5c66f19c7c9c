//! The GPU layout (format 1.4): the node encoder (quantized child boxes), the WGSL kernel and its records, the CPU model that walks the GPU sections step
//! for step as the kernel does, and (feature `wgpu`) the tracer that runs the kernel on a device.

#[cfg(feature = "wgpu")]
pub(crate) mod device;
pub(crate) mod encode;
pub(crate) mod model;
pub(crate) mod refit;
pub mod shader;

#[cfg(feature = "wgpu")]
pub use device::{GPU_BATCH_RAYS, GpuError, GpuTrace, GpuTracer};
pub use encode::quantize_node;
pub use model::{GPU_NODE_BYTES, GPU_TRIANGLE_BYTES, GpuLayoutTracer};
