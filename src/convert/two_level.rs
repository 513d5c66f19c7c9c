//! The conversion of a scene whose import kept meshes instanced: a two-level file (format 1.3). Each instanced
//! mesh is one part, built, split, optimized, collapsed and packed once in its object space
//! ([`super::part::build_part`], as a one-level file's tree is); the flattened rest of the scene, if any, is
//! one more part placed once as it is, and comes first. The top-level tree is built over the instances' world
//! boxes ([`crate::instancing`]). Parts are made one after the other, each with the whole thread pool, so the
//! bytes do not depend on the number of threads. With an animation (`--animation`, whose clips keep the meshes
//! they move rigidly instanced), the flattened part is what the poses deform: its tree is chosen for them
//! ([`crate::animation`]) and the metadata's `animation` object records its costs and the moving instances.

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use bvhc_loader::format::NO_INDEX;
use bvhc_loader::write::BvhWriter;

use super::candidates::lap;
use super::files::input_entries;
use super::metadata::{BuildRecord, Metadata, TrianglesRecord, TwoLevelRecord, WideRecord};
use super::part::{PackedPart, build_part, probe_working_set};
use super::report::{ConvertError, ConvertReport, Event, Timings, TwoLevelSummary, WideSummary};
use super::sampled_poses::SampledAnimation;
use super::write::{stream, verify_and_commit};
use crate::animation::{AnimationRecord, MovingInstance};
use crate::import::memory::{BYTES_PER_TRIANGLE, BYTES_PER_TRIANGLE_WITH_CANDIDATES};
use crate::import::{Import, TriangleSoup};
use crate::instancing::{PackedMesh, Placement, TwoLevelScene};
use crate::options::{ConvertOptions, OptionsError};

/// The identity placement of the flattened part.
const IDENTITY: bvhc_loader::format::Affine3x4 = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]];

/// Converts an import with instanced meshes into the two-level file `output`.
pub(super) fn convert_two_level(
    input: &Path,
    output: &Path,
    options: &ConvertOptions,
    imported: Import,
    mut animation: Option<SampledAnimation>,
    mut timings: Timings,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
) -> Result<ConvertReport, ConvertError> {
    if options.gpu.is_some() {
        return Err(OptionsError::inert(
            "--gpu-layout",
            "instanced meshes (a two-level file)",
            "the GPU sections of format 1.4 are for one-level files; add --instancing never",
        )
        .into());
    }
    let Import { soup, files_read, report, instanced, stage, .. } = imported;
    let peak_bytes_per_triangle =
        if options.candidate_count() > 1 { BYTES_PER_TRIANGLE_WITH_CANDIDATES } else { BYTES_PER_TRIANGLE };
    // The parts' triangles, as indices into the soup: the flattened rest first (when there is any), then each
    // instanced mesh's range.
    let mut in_mesh = vec![false; soup.triangles.len()];
    for mesh in &instanced {
        in_mesh[mesh.triangles.clone()].fill(true);
    }
    let flattened: Vec<usize> = (0..soup.triangles.len()).filter(|&t| !in_mesh[t]).collect();
    drop(in_mesh);
    let mut parts: Vec<Vec<usize>> = Vec::new();
    let mut placements: Vec<Placement> = Vec::new();
    // With an animation: the instances its clips move.
    let mut moving_instances = Vec::new();
    let flattened_triangle_count = flattened.len() as u64;
    if !flattened.is_empty() {
        placements.push(Placement {
            mesh_index: 0,
            object_to_world: IDENTITY,
            node_index: NO_INDEX,
            gpu_instance_index: NO_INDEX,
        });
        parts.push(flattened);
    }
    for mesh in &instanced {
        let mesh_index = parts.len() as u32;
        for (i, p) in mesh.placements.iter().enumerate().filter(|(_, p)| p.moving) {
            let instance = (placements.len() + i) as u32;
            moving_instances.push(MovingInstance { instance, node: p.node_index });
        }
        placements.extend(mesh.placements.iter().map(|p| Placement {
            mesh_index,
            object_to_world: p.object_to_world,
            node_index: p.node_index,
            gpu_instance_index: p.gpu_instance_index,
        }));
        parts.push(mesh.triangles.clone().collect());
    }
    let mut meshes = Vec::with_capacity(parts.len());
    // The records' flags, mesh after mesh (the order the meshes' records take in the file).
    let mut record_source_ids = Vec::new();
    let mut largest: Option<(usize, PartFigures)> = None;
    let mut split = false;
    let clips = animation.as_ref().map(|a| a.sampled.0.clone());
    let mut deformed = None;
    for (m, part) in parts.iter().enumerate() {
        let PartArrays { triangles, source_ids, source_vertices } =
            part_arrays(&soup, part, options.write_source_vertices);
        probe_working_set(input, triangles.len(), peak_bytes_per_triangle)?;
        let deforming = |id: u32| soup.is_deforming(id);
        // The flattened part is what the animation deforms (the instanced meshes move rigidly).
        let poses = match animation.take().filter(|_| m == 0 && flattened_triangle_count > 0) {
            Some(animation) => Some(animation.import_poses(input, &soup.sources, &source_ids, &mut timings)?),
            None => None,
        };
        let mut packed = build_part(
            input,
            triangles,
            source_ids,
            source_vertices,
            &deforming,
            poses.as_ref(),
            options,
            observer,
            &mut timings,
        )?;
        drop(poses);
        if let Some(record) = packed.animation.take() {
            deformed = record.costs;
        }
        split |= packed.packed.triangles.len() > packed.triangle_count;
        record_source_ids.extend_from_slice(&packed.source_ids);
        let figures = PartFigures::of(&packed);
        if largest.as_ref().is_none_or(|(_, f)| figures.triangle_count > f.triangle_count) {
            largest = Some((m, figures));
        }
        meshes.push(packed_mesh(packed, options.write_ids));
    }
    let clock = Instant::now();
    let triangle_flags = options.import.opacity.record_flags(&soup, &record_source_ids);
    drop(record_source_ids);
    let TriangleSoup { sources, .. } = soup;
    let animation_record = clips.map(|clips| AnimationRecord { clips, costs: deformed, moving_instances });
    let scene = TwoLevelScene::assemble(meshes, &placements).map_err(ConvertError::Internal)?;
    let inputs = input_entries(input, &files_read)
        .map_err(|source| bvhc_loader::Error::Io { path: input.to_path_buf(), source })?;
    let wide = options.wide.map(|_| WideRecord::counts(scene.wide_nodes.len(), scene.packets.len()));
    let minor = bvhc_loader::format::written_minor(bvhc_loader::format::MinorFeatures {
        wide: wide.is_some(),
        source_vertices: options.write_source_vertices,
        instances: true,
        gpu: false,
        triangle_flags: triangle_flags.is_some(),
    });
    let summary = TwoLevelSummary {
        mesh_count: scene.meshes.len(),
        instance_count: scene.instances.len(),
        placed_triangle_count: report.placed_triangles,
        flattened_triangle_count,
    };
    let metadata = Metadata {
        generator: concat!("bvhc ", env!("CARGO_PKG_VERSION")),
        format_version: format!("{}.{minor}", bvhc_loader::format::VERSION_MAJOR),
        inputs: &inputs,
        build: BuildRecord::of(options),
        cost: None,
        triangles: TrianglesRecord::of(&report, options.import.keep_degenerate),
        wide,
        choice: None,
        sampling: None,
        two_level: Some(TwoLevelRecord {
            instancing: options.import.instancing,
            instanced_meshes: instanced.iter().map(|m| m.mesh_index).collect(),
            mesh_count: summary.mesh_count,
            instance_count: summary.instance_count,
            placed_triangle_count: summary.placed_triangle_count,
            flattened_triangle_count,
        }),
        animation: animation_record.as_ref(),
        usd: stage.as_ref(),
    }
    .to_json();
    let mut writer = BvhWriter::new(&scene.nodes, &scene.triangles)
        .metadata(&metadata)
        .split_references(split)
        .two_level(scene.sections());
    if options.write_ids {
        writer = writer.triangle_ids(&scene.triangle_ids).source_table(&sources);
    }
    if options.write_source_vertices {
        writer = writer.source_vertices(&scene.source_vertices);
    }
    if options.wide.is_some() {
        writer = writer.wide(&scene.wide_nodes, &scene.packets);
    }
    if let Some(flags) = &triangle_flags {
        writer = writer.triangle_flags(flags);
    }
    let (atomic, file_byte_len) = stream(&writer, output)?;
    drop(writer);
    let (node_count, stored_triangle_count) = (scene.nodes.len(), scene.triangles.len());
    let wide_summary = options.wide.map(|_| WideSummary {
        node_count: scene.wide_nodes.len(),
        packet_count: scene.packets.len(),
        cost: largest.as_ref().and_then(|(_, f)| f.wide_cost).unwrap_or(0.0),
    });
    drop(scene);
    verify_and_commit(atomic, input)?;
    timings.write = lap(clock);
    let Some((_, largest)) = largest else {
        return Err(ConvertError::Internal("a two-level scene without meshes".to_string()));
    };
    Ok(ConvertReport {
        output: output.to_path_buf(),
        files_read,
        import: report.clone(),
        optimization: largest.optimization,
        cost: largest.cost,
        triangle_count: report.triangles as usize,
        reference_count: largest.reference_count,
        stored_triangle_count,
        node_count,
        wide: wide_summary,
        gpu: None,
        file_byte_len: file_byte_len as usize,
        timings,
        choice: None,
        sampling: None,
        two_level: Some(summary),
        animation: animation_record,
        notes: Vec::new(),
    })
}

/// What the report keeps of the largest part.
struct PartFigures {
    triangle_count: usize,
    reference_count: usize,
    cost: crate::cost::SahCost,
    wide_cost: Option<f64>,
    optimization: Option<crate::optimize::OptimizeReport>,
}

impl PartFigures {
    fn of(part: &PackedPart) -> PartFigures {
        PartFigures {
            triangle_count: part.triangle_count,
            reference_count: part.reference_count,
            cost: part.cost,
            wide_cost: part.wide.as_ref().map(|(_, summary)| summary.cost),
            optimization: part.optimization.clone(),
        }
    }
}

/// A part's triangles as [`build_part`] takes them: vertices, source ids and (when written) source vertices.
struct PartArrays {
    triangles: Vec<[[f32; 3]; 3]>,
    source_ids: Vec<u32>,
    source_vertices: Vec<[u32; 3]>,
}

/// The arrays of the soup's triangles `part`, in that order.
fn part_arrays(soup: &TriangleSoup, part: &[usize], write_source_vertices: bool) -> PartArrays {
    PartArrays {
        triangles: part.iter().map(|&t| soup.vertices(t)).collect(),
        source_ids: part.iter().map(|&t| soup.source_ids[t]).collect(),
        source_vertices: if write_source_vertices {
            part.iter().map(|&t| soup.source_vertices[t]).collect()
        } else {
            Vec::new()
        },
    }
}

/// A packed part as one mesh of the file.
fn packed_mesh(part: PackedPart, write_ids: bool) -> PackedMesh {
    let (wide_nodes, packets) = part.wide.map(|(bvh, _)| bvh.into_parts()).unwrap_or_default();
    PackedMesh {
        nodes: part.packed.nodes,
        triangles: part.packed.triangles,
        triangle_ids: if write_ids { part.source_ids } else { Vec::new() },
        source_vertices: part.source_vertices,
        wide_nodes,
        packets,
    }
}
