//! The conversion pipeline: import -> build (one triangle or split reference a leaf) -> optimize -> leaf layout
//! (binary leaf merging, wide collapse) -> pack -> write (atomically, verified). Deterministic: the same input
//! and options give the same bytes, whatever the number of threads (nothing that varies between runs, such as
//! times or absolute paths, is written into the file).

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use bvhc_loader::{AtomicOutput, BvhFile, BvhWriter, SourceVertexIndices};

use super::candidates::{Candidate, best_candidate, lap};
use super::files::{input_entries, refuse_output_among};
use super::metadata::{BuildRecord, CostRecord, Metadata, TrianglesRecord};
use super::report::{ConvertError, ConvertReport, Event, Stage, Timings, WideSummary};
use crate::fallible::{collect_exact, probe};
use crate::import::memory::{BYTES_PER_TRIANGLE, BYTES_PER_TRIANGLE_WITH_CANDIDATES};
use crate::import::{TriangleSoup, import_for_peak};
use crate::options::ConvertOptions;
use crate::pack::{pack, pack_wide};

/// Address space a worker thread may take when it first allocates, for the probe before the build: glibc's
/// malloc reserves 64 MiB for each thread's arena, and a thread's stack is 8 MiB. Only reserved, never touched,
/// so this matters only under an address-space limit (`ulimit -v`), where the probe would otherwise pass and a
/// thread's first allocation abort the conversion (measured: `docs/scale.md`).
const THREAD_ADDRESS_SPACE: usize = 72 << 20;

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
    let mut timings = Timings::default();
    bvhc_loader::check_replaceable(output)?;
    refuse_output_among(output, std::slice::from_ref(&input.to_path_buf()))?;
    let _ = observer(Event::Stage(Stage::Import));
    let clock = Instant::now();
    let peak_bytes_per_triangle =
        if options.candidate_count() > 1 { BYTES_PER_TRIANGLE_WITH_CANDIDATES } else { BYTES_PER_TRIANGLE };
    let imported = import_for_peak(input, &options.import, peak_bytes_per_triangle)?;
    timings.import = lap(clock);
    refuse_output_among(output, &imported.files_read)?;
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
    } = soup;
    drop((positions, vertex_indices));
    let soup_source_vertices = if options.write_source_vertices { soup_source_vertices } else { Vec::new() };
    if u32::try_from(triangles.len()).is_err() {
        return Err(ConvertError::TooLarge { path: input.to_path_buf(), count: triangles.len() });
    }
    // The build and optimization allocate many vectors without reporting failure: make sure their estimated
    // peak, beyond the triangles held now, can be allocated before starting (see `crate::fallible`).
    let working_set = triangles.len().saturating_mul(peak_bytes_per_triangle as usize - size_of::<[[f32; 3]; 3]>());
    let threads = rayon::current_num_threads().saturating_mul(THREAD_ADDRESS_SPACE);
    probe(working_set.saturating_add(threads), "building and optimizing the tree")
        .map_err(|e| out_of_memory(input, "building", e))?;
    let (candidate, choice) = best_candidate(input, &triangles, options, observer, &mut timings)?;
    let Candidate { final_tree, wide_tree, reference_count, optimization } = candidate;
    let over_references = reference_count > triangles.len();
    let _ = observer(Event::Stage(Stage::Write));
    let clock = Instant::now();
    let cost = final_tree.sah_cost(options.optimize.constants);
    let packed = pack(&final_tree, &triangles).map_err(|e| out_of_memory(input, "packing", e))?;
    drop(final_tree);
    let triangle_count = triangles.len();
    drop(triangles);
    check_every_triangle_stored(&packed.triangle_ids, triangle_count, over_references)?;
    let stored_triangle_count = packed.triangles.len();
    // The packer numbers triangles by their index in the soup; the file stores their source ids.
    let source_ids = collect_exact(
        packed.triangle_ids.len(),
        packed.triangle_ids.iter().map(|&t| soup_source_ids[t as usize]),
        "the source ids",
    )
    .map_err(|e| out_of_memory(input, "packing", e))?;
    drop(soup_source_ids);
    // Each record's source vertices, in the record's corner order (the soup's order, mirrored already).
    let source_vertices = if options.write_source_vertices {
        let records =
            packed.triangle_ids.iter().map(|&t| SourceVertexIndices { indices: soup_source_vertices[t as usize] });
        collect_exact(packed.triangle_ids.len(), records, "the source vertices")
            .map_err(|e| out_of_memory(input, "packing", e))?
    } else {
        Vec::new()
    };
    drop(soup_source_vertices);
    let wide = match wide_tree {
        Some((wide_tree, costs)) => {
            let split = stored_triangle_count > triangle_count;
            let bvh = if split {
                let mut records =
                    packed.record_cursor(triangle_count).map_err(|e| out_of_memory(input, "packing", e))?;
                pack_wide(&wide_tree, &packed.triangles, &mut |t| records.next(t), true)
                    .map_err(|e| out_of_memory(input, "packing", e))?
            } else {
                let file_index_of =
                    packed.file_index_of(triangle_count).map_err(|e| out_of_memory(input, "packing", e))?;
                pack_wide(&wide_tree, &packed.triangles, &mut |t| file_index_of.get(t as usize).copied(), false)
                    .map_err(|e| out_of_memory(input, "packing", e))?
            };
            let summary = WideSummary {
                node_count: bvh.nodes().len(),
                packet_count: bvh.packets().len(),
                cost: wide_tree.cost(&costs),
            };
            Some((bvh, summary))
        }
        None => None,
    };
    timings.pack = lap(clock);
    let clock = Instant::now();
    let inputs = input_entries(input, &imported.files_read)
        .map_err(|source| bvhc_loader::Error::Io { path: input.to_path_buf(), source })?;
    let summary = wide.as_ref().map(|(_, summary)| *summary);
    let minor = bvhc_loader::format::written_minor(summary.is_some(), options.write_source_vertices, false);
    let metadata = Metadata {
        generator: concat!("bvhc ", env!("CARGO_PKG_VERSION")),
        format_version: format!("{}.{minor}", bvhc_loader::format::VERSION_MAJOR),
        inputs: &inputs,
        build: BuildRecord::of(options),
        cost: CostRecord::of(&cost, options),
        triangles: TrianglesRecord::of(&imported.report, options.import.keep_degenerate),
        wide: summary,
        choice: choice.as_ref(),
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
    // Streamed to a temporary file, then read back and verified in full once the packed arrays are freed, so
    // the file is in memory once (laying it out in memory beside the arrays took twice its size); the output
    // is replaced only by a verified file. Both transfers bypass the page cache where the system allows it
    // (see `UncachedWriter`), which was most of the write stage's time for large files.
    let mut atomic = AtomicOutput::create(output)?;
    let mut sink = atomic.uncached_writer();
    writer.write_unverified(&mut sink, output)?;
    let file_byte_len =
        sink.finish().map_err(|source| bvhc_loader::Error::Io { path: output.to_path_buf(), source })?;
    let node_count = packed.nodes.len();
    drop(writer);
    drop((packed, wide, source_ids, source_vertices));
    let file = BvhFile::read_uncached(atomic.temporary_path())
        .map_err(|e| out_of_memory(input, "reading the written file back", e))?;
    file.view().verify().map_err(bvhc_loader::Error::from)?;
    drop(file);
    atomic.commit()?;
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
        file_byte_len: file_byte_len as usize,
        timings,
        choice,
    })
}

/// The file may legally repeat triangles (split references), so its verifier cannot notice a triangle lost or
/// doubled by a builder bug; this O(n) check refuses to write such a tree: every triangle at least once, and
/// exactly once without splits.
fn check_every_triangle_stored(ids: &[u32], triangle_count: usize, split: bool) -> Result<(), ConvertError> {
    let mut seen = vec![false; triangle_count];
    let mut repeated = false;
    for &t in ids {
        let Some(slot) = seen.get_mut(t as usize) else {
            return Err(ConvertError::Internal(format!("the built tree holds triangle {t} of {triangle_count}")));
        };
        repeated |= std::mem::replace(slot, true);
    }
    if let Some(t) = seen.iter().position(|&s| !s) {
        return Err(ConvertError::Internal(format!("the built tree lost triangle {t}")));
    }
    if repeated && !split {
        return Err(ConvertError::Internal("the built tree holds a triangle twice without split references".into()));
    }
    Ok(())
}

/// `error` as the conversion's error: [`ConvertError::OutOfMemory`] naming `input` and `stage` when the system
/// refused memory, otherwise a write error.
fn out_of_memory(input: &Path, stage: &'static str, error: bvhc_loader::Error) -> ConvertError {
    let refused = match &error {
        bvhc_loader::Error::OutOfMemory { .. } => true,
        bvhc_loader::Error::Io { source, .. } => source.kind() == std::io::ErrorKind::OutOfMemory,
        _ => false,
    };
    if refused {
        ConvertError::OutOfMemory { path: input.to_path_buf(), stage, source: error }
    } else {
        ConvertError::Write(error)
    }
}
