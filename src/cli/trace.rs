//! `bvhc trace FILE.bvh --rays RAYS.bin [-o HITS.bin] [--any-hit] [--gpu] [--json]`: traces a binary ray file
//! through the loader's `Tracer` (the same kernel a renderer links), in parallel over fixed chunks of rays (so
//! the hits do not depend on `--threads`), or with `--gpu` through its WGSL kernel on the first wgpu adapter.
//! The kernel's batch calls write each ray's record straight into the output buffer, allocated and written
//! once before the clock starts, so the reported seconds and rays per second are the tracing alone; the total
//! (reading, verifying, tracing, writing) is reported beside them. Record layouts:
//! `format-spec/rays-and-hits.md`.

use bvhc_loader::Order;
use bvhc_loader::Trace;
use std::time::Instant;

use bvhc::loader::{BatchRayError, Hit, HitCore, Ray};
use rayon::prelude::*;

use bvhc::sampling::{parse_rays, read_ray_file};

use super::args::TraceArgs;
use super::info::read_verified;
use super::output::print;
use super::{Exit, fail};

/// Bytes of one closest-hit record.
pub const HIT_RECORD_BYTE_LEN: usize = 24;
/// `triangle_index`, `source_triangle_id` and `instance_index` of a miss, `source_triangle_id` of a file without
/// ids, and `instance_index` of a one-level file's hit.
pub const NO_INDEX: u32 = u32::MAX;
/// Rays per parallel chunk.
const CHUNK: usize = 4096;
/// The 24-byte record of a closest-hit result.
pub fn hit_record(hit: Option<&Hit>) -> [u8; HIT_RECORD_BYTE_LEN] {
    match hit {
        Some(h) => record_of(&h.core(), h.source_triangle_id.unwrap_or(NO_INDEX)),
        None => record_of(
            &HitCore { t: f32::INFINITY, triangle_index: NO_INDEX, u: 0.0, v: 0.0, instance_index: None },
            NO_INDEX,
        ),
    }
}

/// [`hit_record`] of a hit handed off lean: its source id looked up in the file's `ids` (the triangle_ids
/// section, parallel to the triangles), as [`Hit::source_triangle_id`] is.
fn core_record(core: &HitCore, ids: Option<&[u32]>) -> [u8; HIT_RECORD_BYTE_LEN] {
    let source = ids.and_then(|ids| ids.get(core.triangle_index as usize)).copied().unwrap_or(NO_INDEX);
    record_of(core, source)
}

/// The record's bytes: `t`, record, source id, `u`, `v`, instance, little-endian.
fn record_of(core: &HitCore, source: u32) -> [u8; HIT_RECORD_BYTE_LEN] {
    let (t, triangle, u, v) = (core.t, core.triangle_index, core.u, core.v);
    let instance = core.instance_index.unwrap_or(NO_INDEX);
    let mut record = [0u8; HIT_RECORD_BYTE_LEN];
    record[0..4].copy_from_slice(&t.to_le_bytes());
    record[4..8].copy_from_slice(&triangle.to_le_bytes());
    record[8..12].copy_from_slice(&source.to_le_bytes());
    record[12..16].copy_from_slice(&u.to_le_bytes());
    record[16..20].copy_from_slice(&v.to_le_bytes());
    record[20..24].copy_from_slice(&instance.to_le_bytes());
    record
}

/// Runs `bvhc trace`.
pub fn trace(args: &TraceArgs) -> Exit {
    let started = Instant::now();
    if let Some(output) = &args.output
        && [&args.file, &args.rays].iter().any(|input| bvhc::convert::files::is_same_file(output, input))
    {
        return fail(Exit::Io, format!("{}: the output is one of the inputs; choose another path", output.display()));
    }
    let file = match read_verified(&args.file) {
        Ok(file) => file,
        Err(exit) => return exit,
    };
    let view = file.view();
    let bytes = match read_ray_file(&args.rays) {
        Ok(bytes) => bytes,
        Err(message) => return fail(Exit::Io, format!("{}: {message}", args.rays.display())),
    };
    let rays = match parse_rays(&bytes) {
        Ok(rays) => rays,
        Err(message) => return fail(Exit::InvalidInput, format!("{}: {message}", args.rays.display())),
    };
    drop(bytes);
    let traced = match args.gpu {
        true => trace_on_gpu(&view, &rays, args.any_hit),
        false => trace_on_cpu(&view, &rays, args),
    };
    let Traced { records, hits, seconds, device, cpu_rays } = match traced {
        Ok(traced) => traced,
        Err((exit, message)) => return fail(exit, format!("{}: {message}", args.file.display())),
    };
    if let Some(output) = &args.output
        && let Err(error) = super::output::write_output(output, &records)
    {
        return fail(Exit::Io, error);
    }
    let total_seconds = started.elapsed().as_secs_f64();
    let rays_per_second = if seconds > 0.0 { rays.len() as f64 / seconds } else { 0.0 };
    let text = if args.json {
        let mut report = serde_json::json!({
            "file": args.file,
            "rays": rays.len(),
            "hits": hits,
            "any_hit": args.any_hit,
            "coherent": args.coherent,
            "device": device,
            "threads": rayon::current_num_threads(),
            "seconds": seconds,
            "rays_per_second": rays_per_second,
            "total_seconds": total_seconds,
        });
        if let Some(cpu_rays) = cpu_rays {
            report["cpu_rays"] = cpu_rays.into();
        }
        format!("{report:#}\n")
    } else {
        let refined = match cpu_rays {
            Some(n) => format!(" ({n} rays' closest hits refined on the CPU)"),
            None => String::new(),
        };
        format!(
            "{}: {} rays, {hits} hit ({}), {seconds:.3} s tracing, {:.2} Mrays/s on {device}{refined}; {total_seconds:.3} s in all\n",
            args.rays.display(),
            rays.len(),
            if args.any_hit { "any hit" } else { "closest hit" },
            rays_per_second / 1e6,
        )
    };
    print(&text, Exit::Success)
}

/// What a trace produced: the output records, the hits, the seconds of tracing, what traced them, and on a GPU
/// the rays it left to the CPU model.
struct Traced {
    records: Vec<u8>,
    hits: usize,
    seconds: f64,
    device: String,
    cpu_rays: Option<usize>,
}

/// The records of `rays` traced by the loader's default CPU kernel on the thread pool: each chunk's batch call
/// writes its rays' records in place, into a buffer that holds a miss's record for every ray before the clock
/// starts (so no page is first touched, and nothing converted, while it runs).
fn trace_on_cpu(view: &bvhc::loader::BvhView<'_>, rays: &[Ray], args: &TraceArgs) -> Result<Traced, (Exit, String)> {
    // `parse_rays` checked every ray against the contract, so the tracer need not check them again.
    let tracer = view.tracer().trusting_rays();
    let order = if args.coherent { Order::Coherent } else { Order::Stream };
    let mut records = match args.any_hit {
        true => vec![0u8; rays.len()],
        false => hit_record(None).repeat(rays.len()),
    };
    records.iter_mut().step_by(4096).for_each(|b| *b = std::hint::black_box(*b)); // touch every page
    let start = Instant::now();
    let traced = if args.any_hit {
        traced_in_place(rays, &mut records, 1, |chunk, each| {
            tracer.any_hits_with(chunk, order, |i, occluded| each(i, occluded.then_some(&[1][..])))
        })
    } else {
        // The lean hand-off: the record needs no normal or side, and its source id is one lookup.
        let ids = view.triangle_ids();
        traced_in_place(rays, &mut records, HIT_RECORD_BYTE_LEN, |chunk, each| {
            tracer.closest_hit_cores_with(chunk, order, |i, core: Option<HitCore>| {
                each(i, core.map(|c| core_record(&c, ids)).as_ref().map(|r| &r[..]))
            })
        })
    };
    let seconds = start.elapsed().as_secs_f64();
    // Unreachable with checked rays; reported rather than trusted.
    let hits = traced.map_err(|why| (Exit::InvalidInput, why))?;
    Ok(Traced { records, hits, seconds, device: format!("{} threads", rayon::current_num_threads()), cpu_rays: None })
}

/// Traces `rays` chunk by chunk on the thread pool, each chunk's records written in place into its part of
/// `records` (`record_len` bytes a ray): `trace(chunk, each)` calls `each(i, record)` once for ray `i` of the
/// chunk, with the record of a hit, or `None` for a miss (whose record is already there). The hits, or the
/// first ray that breaks the contract, named by its index in the file.
fn traced_in_place(
    rays: &[Ray],
    records: &mut [u8],
    record_len: usize,
    trace: impl Fn(&[Ray], &mut dyn FnMut(usize, Option<&[u8]>)) -> Result<(), BatchRayError> + Sync,
) -> Result<usize, String> {
    rays.par_chunks(CHUNK)
        .zip(records.par_chunks_mut(CHUNK * record_len))
        .enumerate()
        .map(|(c, (chunk, out))| {
            let mut hits = 0;
            let mut each = |i: usize, record: Option<&[u8]>| {
                if let Some(record) = record {
                    out[i * record_len..][..record_len].copy_from_slice(record);
                    hits += 1;
                }
            };
            trace(chunk, &mut each).map(|()| hits).map_err(|e| format!("ray {}: {}", c * CHUNK + e.index, e.error))
        })
        .sum()
}

/// The records of `rays` traced by the loader's WGSL kernel on the first wgpu adapter; the seconds count the
/// dispatches and readbacks, not the upload of the sections.
fn trace_on_gpu(view: &bvhc::loader::BvhView<'_>, rays: &[Ray], any_hit: bool) -> Result<Traced, (Exit, String)> {
    use bvhc::loader::{gpu::GpuError, gpu::GpuTracer};
    let tracer = GpuTracer::new(view).map_err(|e| match e {
        GpuError::NoGpuSections => (Exit::InvalidInput, e.to_string()),
        _ => (Exit::Io, e.to_string()),
    })?;
    let device = tracer.adapter_info().map_or("a GPU".to_string(), |a| format!("{} ({:?})", a.name, a.backend));
    let trace = tracer.trace(rays, any_hit).map_err(|e| (Exit::Io, e.to_string()))?;
    let (triangles, ids) = (view.triangles(), view.triangle_ids());
    let (records, hits): (Vec<u8>, usize) = if any_hit {
        let occluded: Vec<u8> =
            trace.records.iter().map(|r| u8::from(r.triangle != bvhc::loader::gpu::shader::GPU_NO_HIT)).collect();
        let hits = occluded.iter().filter(|&&o| o == 1).count();
        (occluded, hits)
    } else {
        let mut hits = 0;
        let records = rays
            .iter()
            .zip(&trace.records)
            .flat_map(|(ray, r)| {
                let hit = r.to_hit(ray, triangles, ids);
                hits += usize::from(hit.is_some());
                hit_record(hit.as_ref())
            })
            .collect();
        (records, hits)
    };
    Ok(Traced { records, hits, seconds: trace.seconds, device, cpu_rays: Some(trace.cpu_rays) })
}
