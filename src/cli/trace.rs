//! `bvhc trace FILE.bvh --rays RAYS.bin [-o HITS.bin] [--any-hit] [--gpu] [--json]`: traces a binary ray file
//! through the loader's `Tracer` (the same kernel a renderer links), in parallel over fixed chunks of rays (so
//! the hits do not depend on `--threads`), or with `--gpu` through its WGSL kernel on the first wgpu adapter,
//! and reports rays per second of the tracing alone. Record layouts:
//! `format-spec/rays-and-hits.md`.

use std::time::Instant;

use bvhc::loader::{Hit, Ray};
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
    let (t, triangle, source, u, v, instance) = match hit {
        Some(h) => (
            h.t,
            h.triangle_index,
            h.source_triangle_id.unwrap_or(NO_INDEX),
            h.u,
            h.v,
            h.instance_index.unwrap_or(NO_INDEX),
        ),
        None => (f32::INFINITY, NO_INDEX, NO_INDEX, 0.0, 0.0, NO_INDEX),
    };
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
        false => Ok(trace_on_cpu(&view, &rays, args)),
    };
    let Traced { records, hits, seconds, device } = match traced {
        Ok(traced) => traced,
        Err((exit, message)) => return fail(exit, format!("{}: {message}", args.file.display())),
    };
    if let Some(output) = &args.output
        && let Err(error) = super::output::write_output(output, &records)
    {
        return fail(Exit::Io, error);
    }
    let rays_per_second = if seconds > 0.0 { rays.len() as f64 / seconds } else { 0.0 };
    let text = if args.json {
        let report = serde_json::json!({
            "file": args.file,
            "rays": rays.len(),
            "hits": hits,
            "any_hit": args.any_hit,
            "coherent": args.coherent,
            "device": device,
            "threads": rayon::current_num_threads(),
            "seconds": seconds,
            "rays_per_second": rays_per_second,
        });
        format!("{report:#}\n")
    } else {
        format!(
            "{}: {} rays, {hits} hit ({}), {seconds:.3} s tracing, {:.2} Mrays/s on {device}\n",
            args.rays.display(),
            rays.len(),
            if args.any_hit { "any hit" } else { "closest hit" },
            rays_per_second / 1e6,
        )
    };
    print(&text, Exit::Success)
}

/// What a trace produced: the output records, the hits, the seconds of tracing, and what traced them.
struct Traced {
    records: Vec<u8>,
    hits: usize,
    seconds: f64,
    device: String,
}

/// The records of `rays` traced by the loader's default CPU kernel on the thread pool.
fn trace_on_cpu(view: &bvhc::loader::BvhView<'_>, rays: &[Ray], args: &TraceArgs) -> Traced {
    // `parse_rays` checked every ray against the contract, so the tracer need not check them again.
    let tracer = view.tracer().trusting_rays();
    let start = Instant::now();
    let (records, hits): (Vec<u8>, usize) = if args.any_hit {
        let mut flags = vec![false; rays.len()];
        rays.par_chunks(CHUNK).zip(flags.par_chunks_mut(CHUNK)).for_each(|(c, out)| match args.coherent {
            true => tracer.any_hits_coherent(c, out),
            false => tracer.any_hits(c, out),
        });
        let occluded: Vec<u8> = flags.into_iter().map(u8::from).collect();
        let hits = occluded.iter().filter(|&&o| o == 1).count();
        (occluded, hits)
    } else {
        let mut found: Vec<Option<Hit>> = vec![None; rays.len()];
        rays.par_chunks(CHUNK).zip(found.par_chunks_mut(CHUNK)).for_each(|(c, out)| match args.coherent {
            true => tracer.closest_hits_coherent(c, out),
            false => tracer.closest_hits(c, out),
        });
        let hits = found.iter().filter(|h| h.is_some()).count();
        (found.iter().flat_map(|h| hit_record(h.as_ref())).collect(), hits)
    };
    let seconds = start.elapsed().as_secs_f64();
    Traced { records, hits, seconds, device: format!("{} threads", rayon::current_num_threads()) }
}

/// The records of `rays` traced by the loader's WGSL kernel on the first wgpu adapter; the seconds count the
/// dispatches and readbacks, not the upload of the sections.
fn trace_on_gpu(view: &bvhc::loader::BvhView<'_>, rays: &[Ray], any_hit: bool) -> Result<Traced, (Exit, String)> {
    use bvhc::loader::{GpuError, GpuTracer};
    let tracer = GpuTracer::new(view).map_err(|e| match e {
        GpuError::NoGpuSections => (Exit::InvalidInput, e.to_string()),
        _ => (Exit::Io, e.to_string()),
    })?;
    let device = tracer.adapter_info().map_or("a GPU".to_string(), |a| format!("{} ({:?})", a.name, a.backend));
    let trace = tracer.trace(rays, any_hit).map_err(|e| (Exit::Io, e.to_string()))?;
    let (triangles, ids) = (view.triangles(), view.triangle_ids());
    let (records, hits): (Vec<u8>, usize) = if any_hit {
        let occluded: Vec<u8> =
            trace.records.iter().map(|r| u8::from(r.triangle != bvhc::loader::gpu_shader::GPU_NO_HIT)).collect();
        let hits = occluded.iter().filter(|&&o| o == 1).count();
        (occluded, hits)
    } else {
        let found: Vec<Option<Hit>> =
            rays.iter().zip(&trace.records).map(|(ray, r)| r.to_hit(ray, triangles, ids)).collect();
        let hits = found.iter().filter(|h| h.is_some()).count();
        (found.iter().flat_map(|h| hit_record(h.as_ref())).collect(), hits)
    };
    Ok(Traced { records, hits, seconds: trace.seconds, device })
}
