//! [`GpuTracer`] (feature `wgpu`): the WGSL kernel ([`crate::gpu::shader`]) run through wgpu on any adapter,
//! including software ones (Mesa's lavapipe). The GPU sections are uploaded once, straight from the file's bytes
//! (a mapped file's pages are copied to the device with no repacking); rays are traced in batches of up to
//! [`GPU_BATCH_RAYS`], each one dispatch, one copy and one readback.

use std::fmt;
use std::time::Instant;

use wgpu::util::DeviceExt;

use crate::format::PackedTriangle;
use crate::gpu::model::GpuLayoutTracer;
use crate::gpu::shader::{GPU_TRAVERSAL_WGSL, GPU_WORKGROUP_SIZE, GpuHitRecord, GpuParams, GpuRay};
use crate::open::sections::GpuSections;
use crate::open::view::BvhView;
use crate::ray::hit::Hit;
use crate::ray::intersect::Ray;

/// Rays a [`GpuTracer`] sends in one dispatch (32 MiB of rays, 16 MiB of results).
pub const GPU_BATCH_RAYS: usize = 1 << 20;

/// Why the GPU kernel could not run.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum GpuError {
    /// The file has no GPU sections: convert it with `bvhc --gpu-layout`.
    NoGpuSections,
    /// No wgpu adapter (hardware or software) could be found.
    NoAdapter(String),
    /// The adapter refused a device, or a section exceeds its buffer limits.
    Device(String),
    /// The results could not be read back.
    Readback(String),
}

impl fmt::Display for GpuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GpuError::NoGpuSections => write!(
                f,
                "the file has no GPU sections (format 1.4); convert it again with `bvhc SCENE -o FILE --gpu-layout`"
            ),
            GpuError::NoAdapter(why) => write!(f, "no GPU adapter: {why}"),
            GpuError::Device(why) => write!(f, "GPU device: {why}"),
            GpuError::Readback(why) => write!(f, "GPU readback: {why}"),
        }
    }
}

impl std::error::Error for GpuError {}

/// Traces rays through a file's GPU sections on a wgpu device; hits are the CPU kernels' [`Hit`] records (`t`,
/// `u`, `v` within `format-spec/bvh-1.md` 11.4's bound of theirs).
pub struct GpuTracer<'a> {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: Option<wgpu::AdapterInfo>,
    layout: wgpu::BindGroupLayout,
    closest: wgpu::ComputePipeline,
    any: wgpu::ComputePipeline,
    /// The two sections' buffers and the records' source ids (binding 5: the `triangle_ids` section, or one 0
    /// without one); `None` for an empty scene (bindings cannot be empty: every ray misses).
    sections: Option<(wgpu::Buffer, wgpu::Buffer, wgpu::Buffer)>,
    triangles: &'a [PackedTriangle],
    triangle_ids: Option<&'a [u32]>,
    /// The kernel's CPU model, which traces the rays the kernel leaves to the CPU.
    model: GpuLayoutTracer<'a>,
}

/// Records of one batch call and its times.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuTrace {
    /// One per ray: the kernel's, or for a ray it left to the CPU (an ill-conditioned hit,
    /// [`GpuHitRecord::needs_cpu`]) the CPU model's ([`GpuLayoutTracer::record`]).
    pub records: Vec<GpuHitRecord>,
    /// How many rays the kernel left to the CPU.
    pub cpu_rays: usize,
    /// Seconds spent uploading the rays, dispatching, running and reading back (not the section upload).
    pub seconds: f64,
    /// Seconds the kernel ran, from timestamp queries, where the device has them.
    pub kernel_seconds: Option<f64>,
}

impl<'a> GpuTracer<'a> {
    /// A tracer on the first adapter wgpu finds (a high-performance one first, else any, software included),
    /// with the adapter's own buffer limits.
    pub fn new(view: &BvhView<'a>) -> Result<GpuTracer<'a>, GpuError> {
        let gpu = view.gpu_sections().ok_or(GpuError::NoGpuSections)?;
        Ok(GpuTracer::on_sections(gpu, view.triangles(), view.triangle_ids())?
            .with_split_references(view.has_split_references()))
    }

    /// This tracer over a triangles section with the `SPLIT_REFERENCES` flag (`split`; [`GpuTracer::new`] reads
    /// it from the file): hits at one `t` are then ordered by coordinates (`format-spec/bvh-1.md` 11.1).
    pub fn with_split_references(self, split: bool) -> Self {
        GpuTracer { model: self.model.with_split_references(split), ..self }
    }

    /// [`GpuTracer::new`] for sections held elsewhere (a benchmark's other builder, say), in the layout of
    /// [`GpuSections`] (the shader needs the layout, not 1.4's placement rules), over `triangles` and their ids.
    pub fn on_sections(
        gpu: GpuSections<'a>,
        triangles: &'a [PackedTriangle],
        triangle_ids: Option<&'a [u32]>,
    ) -> Result<GpuTracer<'a>, GpuError> {
        let options = |force_fallback_adapter| wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter,
            compatible_surface: None,
            ..wgpu::RequestAdapterOptions::default()
        };
        // Vulkan, Metal, DirectX 12 first (`WGPU_BACKEND` overrides); OpenGL only where none of them has one.
        let mut failure = String::new();
        let mut found = None;
        for backends in [wgpu::Backends::PRIMARY, wgpu::Backends::all()] {
            let mut descriptor = wgpu::InstanceDescriptor::new_without_display_handle_from_env();
            if std::env::var_os("WGPU_BACKEND").is_none() {
                descriptor.backends = backends;
            }
            let instance = wgpu::Instance::new(descriptor);
            match pollster::block_on(instance.request_adapter(&options(false)))
                .or_else(|_| pollster::block_on(instance.request_adapter(&options(true))))
            {
                Ok(adapter) => {
                    found = Some(adapter);
                    break;
                }
                Err(e) => failure = e.to_string(),
            }
        }
        let adapter = found.ok_or(GpuError::NoAdapter(failure))?;
        let descriptor = wgpu::DeviceDescriptor {
            label: Some("bvhc"),
            required_limits: adapter.limits(),
            // Kernel times from timestamps where the adapter has them.
            required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
            ..wgpu::DeviceDescriptor::default()
        };
        let (device, queue) =
            pollster::block_on(adapter.request_device(&descriptor)).map_err(|e| GpuError::Device(e.to_string()))?;
        let mut tracer = GpuTracer::build(device, queue, gpu, triangles, triangle_ids)?;
        tracer.adapter = Some(adapter.get_info());
        Ok(tracer)
    }

    /// A tracer on the caller's device, which must allow storage bindings as large as the file's sections (and
    /// have `TIMESTAMP_QUERY` enabled for [`GpuTrace::kernel_seconds`]).
    pub fn with_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        view: &BvhView<'a>,
    ) -> Result<GpuTracer<'a>, GpuError> {
        let gpu = view.gpu_sections().ok_or(GpuError::NoGpuSections)?;
        Ok(GpuTracer::build(device, queue, gpu, view.triangles(), view.triangle_ids())?
            .with_split_references(view.has_split_references()))
    }

    fn build(
        device: wgpu::Device,
        queue: wgpu::Queue,
        gpu: GpuSections<'a>,
        triangles: &'a [PackedTriangle],
        triangle_ids: Option<&'a [u32]>,
    ) -> Result<GpuTracer<'a>, GpuError> {
        let limit = device.limits().max_storage_buffer_binding_size;
        let node_bytes: &[u8] = bytemuck::cast_slice(gpu.nodes);
        let triangle_bytes: &[u8] = bytemuck::cast_slice(gpu.triangles);
        if node_bytes.len() as u64 > limit || triangle_bytes.len() as u64 > limit {
            return Err(GpuError::Device(format!(
                "the GPU sections ({} and {} bytes) exceed the device's storage binding limit of {limit} bytes",
                node_bytes.len(),
                triangle_bytes.len()
            )));
        }
        // Errors in creating the buffers, the shader or the pipelines become a `GpuError`, not wgpu's panic.
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory_scope = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let storage = |label, contents| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        // The ids order hits at one `t` after the coordinates with split references (11.1's tie key); 4 bytes a
        // record, uploaded whenever the file has them.
        let id_bytes: &[u8] = bytemuck::cast_slice(triangle_ids.filter(|ids| !ids.is_empty()).unwrap_or(&[0]));
        let sections = (!gpu.nodes.is_empty()).then(|| {
            (
                storage("gpu_nodes", node_bytes),
                storage("gpu_triangles", triangle_bytes),
                storage("triangle_ids", id_bytes),
            )
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("bvhc gpu.wgsl"),
            source: wgpu::ShaderSource::Wgsl(GPU_TRAVERSAL_WGSL.into()),
        });
        let entry = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("bvhc gpu bindings"),
            entries: &[
                entry(0, read),
                entry(1, read),
                entry(2, read),
                entry(3, wgpu::BufferBindingType::Storage { read_only: false }),
                entry(4, wgpu::BufferBindingType::Uniform),
                entry(5, read),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("bvhc gpu pipeline"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry_point| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry_point),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry_point),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                cache: None,
            })
        };
        let (closest, any) = (pipeline("closest_hit"), pipeline("any_hit"));
        for scope in [memory_scope, scope] {
            if let Some(error) = pollster::block_on(scope.pop()) {
                return Err(GpuError::Device(error.to_string()));
            }
        }
        let model = GpuLayoutTracer::new(gpu, triangles, triangle_ids);
        Ok(GpuTracer { device, queue, adapter: None, layout, closest, any, sections, triangles, triangle_ids, model })
    }

    /// The adapter [`GpuTracer::new`] chose (`None` on a caller's device).
    pub fn adapter_info(&self) -> Option<&wgpu::AdapterInfo> {
        self.adapter.as_ref()
    }

    /// The closest hit of every ray.
    pub fn closest_hits(&self, rays: &[Ray]) -> Result<Vec<Option<Hit>>, GpuError> {
        let trace = self.trace(rays, false)?;
        Ok(rays.iter().zip(&trace.records).map(|(ray, r)| r.to_hit(ray, self.triangles, self.triangle_ids)).collect())
    }

    /// Whether each ray hits anything.
    pub fn any_hits(&self, rays: &[Ray]) -> Result<Vec<bool>, GpuError> {
        let trace = self.trace(rays, true)?;
        Ok(trace.records.iter().map(|r| r.triangle != crate::gpu::shader::GPU_NO_HIT).collect())
    }

    /// The kernel's records for `rays` (closest hit, or for `any_hit` the first hit found), and the time spent
    /// (including the CPU's tracing of the rays the kernel left to it).
    pub fn trace(&self, rays: &[Ray], any_hit: bool) -> Result<GpuTrace, GpuError> {
        let start = Instant::now();
        let mut records = Vec::with_capacity(rays.len());
        let mut kernel_seconds = Some(0.0);
        for batch in rays.chunks(GPU_BATCH_RAYS) {
            match &self.sections {
                Some(sections) => {
                    let (batch_records, seconds) = self.dispatch(sections, batch, any_hit)?;
                    records.extend(batch_records);
                    kernel_seconds = kernel_seconds.zip(seconds).map(|(a, b)| a + b);
                }
                None => records.extend(batch.iter().map(|_| GpuHitRecord::MISS)),
            }
        }
        let mut cpu_rays = 0;
        for (record, ray) in records.iter_mut().zip(rays) {
            if record.needs_cpu() {
                *record = self.model.record(ray, any_hit);
                cpu_rays += 1;
            }
        }
        Ok(GpuTrace { records, cpu_rays, seconds: start.elapsed().as_secs_f64(), kernel_seconds })
    }

    /// One batch: upload, dispatch, copy, read back; the records and the kernel's seconds from timestamps.
    fn dispatch(
        &self,
        (nodes, triangles, ids): &(wgpu::Buffer, wgpu::Buffer, wgpu::Buffer),
        rays: &[Ray],
        any_hit: bool,
    ) -> Result<(Vec<GpuHitRecord>, Option<f64>), GpuError> {
        let gpu_rays: Vec<GpuRay> = rays.iter().map(GpuRay::new).collect();
        let device = &self.device;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let memory_scope = device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let ray_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("rays"),
            contents: bytemuck::cast_slice(&gpu_rays),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let split_references = u32::from(self.model.splits_references());
        let tie_by_ids = u32::from(self.model.splits_references() && self.triangle_ids.is_some());
        let reach_scale = self.model.reach_scale();
        let params = GpuParams { ray_count: rays.len() as u32, split_references, reach_scale, tie_by_ids };
        let params_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("params"),
            contents: bytemuck::bytes_of(&params),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let hit_bytes = (rays.len() * size_of::<GpuHitRecord>()) as u64;
        let hits = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hits"),
            size: hit_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hits readback"),
            size: hit_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("bvhc gpu"),
            layout: &self.layout,
            entries: &[
                binding(0, nodes),
                binding(1, triangles),
                binding(2, &ray_buffer),
                binding(3, &hits),
                binding(4, &params_buffer),
                binding(5, ids),
            ],
        });
        let timestamps = device.features().contains(wgpu::Features::TIMESTAMP_QUERY).then(|| {
            let queries = device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("kernel time"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            });
            let buffer = |usage| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("timestamps"),
                    size: 16,
                    usage,
                    mapped_at_creation: false,
                })
            };
            let resolved = buffer(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC);
            (queries, resolved, buffer(wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST))
        });
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("trace") });
        {
            let timestamp_writes = timestamps.as_ref().map(|(queries, _, _)| wgpu::ComputePassTimestampWrites {
                query_set: queries,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            });
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: None, timestamp_writes });
            pass.set_pipeline(if any_hit { &self.any } else { &self.closest });
            pass.set_bind_group(0, &bind_group, &[]);
            pass.dispatch_workgroups((rays.len() as u32).div_ceil(GPU_WORKGROUP_SIZE), 1, 1);
        }
        encoder.copy_buffer_to_buffer(&hits, 0, &readback, 0, hit_bytes);
        if let Some((queries, resolved, times)) = &timestamps {
            encoder.resolve_query_set(queries, 0..2, resolved, 0);
            encoder.copy_buffer_to_buffer(resolved, 0, times, 0, 16);
        }
        self.queue.submit([encoder.finish()]);
        for scope in [memory_scope, scope] {
            if let Some(error) = pollster::block_on(scope.pop()) {
                return Err(GpuError::Device(error.to_string()));
            }
        }
        let records: Vec<GpuHitRecord> = read_back(device, &readback)?;
        let kernel_seconds = match &timestamps {
            Some((_, _, times)) => {
                let ticks: Vec<u64> = read_back(device, times)?;
                let period = f64::from(self.queue.get_timestamp_period());
                Some(ticks[1].saturating_sub(ticks[0]) as f64 * period * 1e-9)
            }
            None => None,
        };
        Ok((records, kernel_seconds))
    }
}

/// The contents of a mappable buffer once the queue's work is done.
fn read_back<T: bytemuck::Pod>(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<Vec<T>, GpuError> {
    let (sender, receiver) = std::sync::mpsc::channel();
    buffer.slice(..).map_async(wgpu::MapMode::Read, move |result| {
        let _ = sender.send(result);
    });
    device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| GpuError::Readback(e.to_string()))?;
    receiver.recv().map_err(|e| GpuError::Readback(e.to_string()))?.map_err(|e| GpuError::Readback(e.to_string()))?;
    let values = {
        let view = buffer.slice(..).get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
        bytemuck::pod_collect_to_vec::<u8, T>(&view)
    };
    buffer.unmap();
    Ok(values)
}

/// A bind group entry for a whole buffer.
fn binding(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry { binding, resource: buffer.as_entire_binding() }
}
