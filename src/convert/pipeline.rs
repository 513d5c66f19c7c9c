//! The conversion pipeline: import -> build (one triangle or split reference a leaf) -> optimize -> leaf layout
//! (binary leaf merging, wide collapse) -> pack -> write (atomically, verified). Deterministic: the same input
//! and options give the same bytes, whatever the number of threads (nothing that varies between runs, such as
//! times or absolute paths, is written into the file).

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use bvhc_loader::write::BvhWriter;

use super::candidates::lap;
use super::files::{input_entries, refuse_output_among};
use super::metadata::{BuildRecord, CostRecord, Metadata, TrianglesRecord, WideRecord};
use super::part::{PackedPart, build_part, probe_working_set};
use super::report::{ConvertError, ConvertReport, Event, GpuSummary, Stage, Timings};
use super::sampled_poses::{SampledAnimation, pose_bytes_per_triangle};
use super::write::{stream, verify_and_commit};
use crate::animation::sampled_times;
use crate::import::memory::{BYTES_PER_TRIANGLE, BYTES_PER_TRIANGLE_WITH_CANDIDATES, GPU_LAYOUT_BYTES_PER_TRIANGLE};
use crate::import::{Instancing, SceneFormat, TriangleSoup, import_for_peak};
use crate::options::ConvertOptions;

/// Converts `input` into the `.bvh` file `output` with the default options.
pub fn convert(input: &Path, output: &Path) -> Result<ConvertReport, ConvertError> {
    convert_with(input, output, &ConvertOptions::default(), &mut |_| ControlFlow::Continue(()))
}

/// Converts `input` into `output` (written atomically). `observer` sees every stage and optimizer batch;
/// returning `ControlFlow::Break` on a batch cancels the optimization (the best tree so far is written).
pub fn convert_with(
    input: &Path,
    output: &Path,
    options: &ConvertOptions,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
) -> Result<ConvertReport, ConvertError> {
    options.validate()?;
    let notes = instancing_notes(input, options);
    let mut timings = Timings::default();
    bvhc_loader::write::check_replaceable(output)?;
    refuse_output_among(output, std::slice::from_ref(&input.to_path_buf()))?;
    let _ = observer(Event::Stage(Stage::Import));
    let clock = Instant::now();
    let peak_bytes_per_triangle =
        if options.candidate_count() > 1 { BYTES_PER_TRIANGLE_WITH_CANDIDATES } else { BYTES_PER_TRIANGLE };
    let gpu_bytes_per_triangle = if options.gpu.is_some() { GPU_LAYOUT_BYTES_PER_TRIANGLE } else { 0 };
    // An animation's poses, chosen before the import so that the memory budget counts their triangles and boxes.
    let sampled = options.animation.as_ref().map(|a| sampled_times(input, &options.import, a)).transpose()?;
    let pose_bytes_per_triangle = sampled.as_ref().map_or(0, |(_, times)| pose_bytes_per_triangle(times.len()));
    let peak_bytes_per_triangle = peak_bytes_per_triangle + gpu_bytes_per_triangle + pose_bytes_per_triangle;
    // The animation's clips keep the meshes they move rigidly instanced (unless --instancing never).
    let mut import_options = options.import.clone();
    if let Some((clips, _)) = &sampled {
        import_options.moving_clips = clips.iter().map(|clip| clip.index).collect();
    }
    let imported = import_for_peak(input, &import_options, peak_bytes_per_triangle)?;
    timings.import = lap(clock);
    refuse_output_among(output, &imported.files_read)?;
    let animation = sampled.map(|sampled| SampledAnimation { sampled, import: import_options });
    if !imported.instanced.is_empty() {
        return super::two_level::convert_two_level(input, output, options, imported, animation, timings, observer);
    }
    let soup = imported.soup;
    let triangles = soup.triangle_vertices();
    // Each large intermediate is dropped once its stage is done, so the peak is one stage's working set: here
    // the soup's vertices and indices (the triangles hold the positions now).
    let TriangleSoup {
        positions,
        triangles: vertex_indices,
        source_ids: soup_source_ids,
        sources: soup_sources,
        source_vertices: soup_source_vertices,
        cut_out,
        deforming,
    } = soup;
    // Only the source ranges are needed to mark the records of cut-out materials (after the build) and to
    // know the geometry meant to deform (during it).
    let ranges = TriangleSoup { sources: soup_sources, cut_out, deforming, ..TriangleSoup::default() };
    drop((positions, vertex_indices));
    let soup_source_vertices = if options.write_source_vertices { soup_source_vertices } else { Vec::new() };
    if u32::try_from(triangles.len()).is_err() {
        return Err(ConvertError::TooLarge { path: input.to_path_buf(), count: triangles.len() });
    }
    // The build and optimization allocate many vectors without reporting failure: make sure their estimated
    // peak, beyond the triangles held now, can be allocated before starting (see `crate::fallible`).
    probe_working_set(input, triangles.len(), peak_bytes_per_triangle)?;
    let deforming = |id: u32| ranges.is_deforming(id);
    let poses = match animation {
        Some(animation) => Some(animation.import_poses(input, &ranges.sources, &soup_source_ids, &mut timings)?),
        None => None,
    };
    let part = build_part(
        input,
        triangles,
        soup_source_ids,
        soup_source_vertices,
        &deforming,
        poses.as_ref(),
        options,
        observer,
        &mut timings,
    )?;
    let PackedPart {
        packed,
        source_ids,
        source_vertices,
        wide,
        gpu,
        cost,
        triangle_count,
        reference_count,
        optimization,
        choice,
        sampling,
        animation,
    } = part;
    drop(poses);
    let stored_triangle_count = packed.triangles.len();
    let clock = Instant::now();
    let inputs = input_entries(input, &imported.files_read)
        .map_err(|source| bvhc_loader::Error::Io { path: input.to_path_buf(), source })?;
    let summary = wide.as_ref().map(|(_, summary)| *summary);
    let triangle_flags = options.import.opacity.record_flags(&ranges, &source_ids);
    let soup_sources = ranges.sources;
    let minor = bvhc_loader::format::written_minor(bvhc_loader::format::MinorFeatures {
        wide: summary.is_some(),
        source_vertices: options.write_source_vertices,
        instances: false,
        gpu: gpu.is_some(),
        triangle_flags: triangle_flags.is_some(),
    });
    let metadata = Metadata {
        generator: concat!("bvhc ", env!("CARGO_PKG_VERSION")),
        format_version: format!("{}.{minor}", bvhc_loader::format::VERSION_MAJOR),
        inputs: &inputs,
        build: BuildRecord::of(options),
        cost: Some(CostRecord::of(&cost, options)),
        triangles: TrianglesRecord::of(&imported.report, options.import.keep_degenerate),
        wide: summary.as_ref().map(WideRecord::of),
        choice: choice.as_ref(),
        sampling: sampling.as_ref(),
        two_level: None,
        animation: animation.as_ref(),
        usd: imported.stage.as_ref(),
    }
    .to_json();
    let mut writer = BvhWriter::new(&packed.nodes, &packed.triangles)
        .metadata(&metadata)
        .split_references(stored_triangle_count > triangle_count);
    if options.write_ids {
        writer = writer.triangle_ids(&source_ids).source_table(&soup_sources);
    }
    if options.write_source_vertices {
        writer = writer.source_vertices(&source_vertices);
    }
    if let Some((bvh, _)) = &wide {
        writer = writer.wide(bvh.nodes(), bvh.packets());
    }
    if let Some(layout) = &gpu {
        writer = writer.gpu(&layout.nodes, &layout.triangles);
    }
    if let Some(flags) = &triangle_flags {
        writer = writer.triangle_flags(flags);
    }
    let (atomic, file_byte_len) = stream(&writer, output)?;
    let node_count = packed.nodes.len();
    let gpu_summary = gpu
        .as_ref()
        .map(|layout| GpuSummary { node_count: layout.nodes.len(), triangle_count: layout.triangles.len() });
    drop(writer);
    drop((packed, wide, gpu, source_ids, source_vertices));
    verify_and_commit(atomic, input)?;
    timings.write = lap(clock);
    Ok(ConvertReport {
        output: output.to_path_buf(),
        files_read: imported.files_read,
        import: imported.report,
        optimization,
        cost,
        triangle_count,
        reference_count,
        stored_triangle_count,
        node_count,
        wide: summary,
        gpu: gpu_summary,
        file_byte_len: file_byte_len as usize,
        timings,
        choice,
        sampling,
        two_level: None,
        animation,
        notes,
    })
}

/// `--instancing always` or `never` on an OBJ or PLY input: such a file places each model once, so it satisfies
/// either setting by its nature (nothing is instanced). Accepted, so a build script can pass one set of options
/// to a list of mixed assets, with a note that says so.
fn instancing_notes(input: &Path, options: &ConvertOptions) -> Vec<String> {
    let mode = options.import.instancing;
    let name = input.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let format = SceneFormat::from_file_name(&name).map(|(format, _)| format);
    if mode == Instancing::Auto || !matches!(format, Some(SceneFormat::Obj | SceneFormat::Ply)) {
        return Vec::new();
    }
    vec![format!(
        "--instancing {}: {name} is an OBJ or PLY file, which places each model once, so nothing is instanced",
        mode.name()
    )]
}
