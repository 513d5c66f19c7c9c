//! The meshes a stage draws, read and handed to the soup: flattened into world space, or, for a [`Unit`] kept
//! instanced, stored once in the unit's space and placed by instances. Which units stay instanced follows the
//! import's [`Instancing`] policy as for glTF meshes ([`choose_instanced`]), a unit standing for a mesh and
//! its placements for the mesh's, but for `auto`: a stage's author asked for each unit to be instanced (an
//! instanceable prim, a point instancer), so under `auto` every unit placed more than once stays instanced, as
//! under `always`.
//!
//! Provenance: a source range's `mesh_index` is the mesh prim's index in [`StageRecord::prims`], its
//! `node_index` the placing prim's (the instance prim or the point instancer; `NO_INDEX` for a mesh drawn where
//! it stands) and its `instance_index` the point instancer's instance; an instanced unit's triangles name their
//! mesh prims, and each instance names its placing prim.

use std::collections::HashMap;

use bvhc_loader::format::NO_INDEX;
use glam::DMat4;
use openusd::usd::{Stage, TimeCode};

use super::StageRecord;
use super::walk::{PlacedMesh, Scene, Unit};
use super::{mesh, skel};
use crate::import::instancing::{InstancedMesh, MeshPlacement, affine, choose_instanced, stored_triangles};
use crate::import::soup::{PrimitiveInstance, Provenance, SoupBuilder};
use crate::import::{ErrorKind, ImportOptions, Instancing, Located};

/// Adds the scene's meshes to `builder`; returns the units kept instanced.
pub(super) fn emit(
    stage: &Stage,
    scene: &Scene,
    time: Option<TimeCode>,
    options: &ImportOptions,
    builder: &mut SoupBuilder,
    record: &mut StageRecord,
) -> Result<Vec<InstancedMesh>, Located> {
    let mut emitter = Emitter { stage, time, builder, record, prim_index: HashMap::new(), read: HashMap::new() };
    // Triangles each mesh declares, counted from its topology before any points are read.
    let declared = |mesh: &PlacedMesh| -> Result<u64, Located> {
        mesh::declared_triangles(&stage.prim(mesh.path.as_str())).map_err(|e| at(&mesh.path, e))
    };
    let mut file_triangles = 0u64;
    let mut placements = vec![1u64; scene.meshes.len()];
    let mut triangles = Vec::with_capacity(scene.meshes.len() + scene.units.len());
    for mesh in &scene.meshes {
        let count = declared(mesh)?;
        file_triangles = file_triangles.saturating_add(count);
        triangles.push(count);
    }
    for unit in &scene.units {
        let mut sum = 0u64;
        for mesh in &unit.meshes {
            sum = sum.saturating_add(declared(mesh)?);
        }
        file_triangles = file_triangles.saturating_add(sum);
        placements.push(unit.placements.len() as u64);
        triangles.push(sum);
    }
    emitter.builder.report.file_mesh_triangles = file_triangles;
    let total_placements = placements.iter().fold(0u64, |a, &p| a.saturating_add(p));
    emitter
        .builder
        .placement_budget
        .take(total_placements)
        .map_err(|e| Located::of_kind(ErrorKind::Limit, "stage", e))?;
    let fits = |stored| emitter.builder.check_memory(stored).is_ok();
    // A stage's author asked for its units to be instanced (an instanceable prim, a point instancer): under
    // `auto` they stay instanced whatever their size; `never` flattens them.
    let mode = match options.instancing {
        Instancing::Auto => Instancing::Always,
        other => other,
    };
    let chosen = choose_instanced(mode, &placements, &triangles, fits);
    emitter
        .builder
        .check_memory(stored_triangles(&placements, &triangles, &chosen))
        .map_err(|e| Located::of_kind(ErrorKind::Limit, "stage", e))?;
    for mesh in &scene.meshes {
        emitter.add(mesh, mesh.transform, None, None)?;
        emitter.builder.report.mesh_placements += 1;
    }
    let mut instanced = Vec::new();
    for (unit, keep) in scene.units.iter().zip(&chosen[scene.meshes.len()..]) {
        emitter.unit(unit, *keep, &mut instanced)?;
    }
    Ok(instanced)
}

fn at(path: &str, message: String) -> Located {
    Located::new(&format!("prim {path}"), message)
}

struct Emitter<'a> {
    stage: &'a Stage,
    time: Option<TimeCode>,
    builder: &'a mut SoupBuilder,
    record: &'a mut StageRecord,
    /// Prim path -> index in `record.prims`.
    prim_index: HashMap<String, u32>,
    /// Mesh prims read so far.
    read: HashMap<String, mesh::MeshGeometry>,
}

impl Emitter<'_> {
    /// The index of `path` in the record's prims, added on first use.
    fn prim(&mut self, path: &str) -> u32 {
        if let Some(&index) = self.prim_index.get(path) {
            return index;
        }
        let index = self.record.prims.len() as u32;
        self.record.prims.push(path.to_string());
        self.prim_index.insert(path.to_string(), index);
        index
    }

    /// One unit: its meshes once in its own space and an instance a placement, or every placement flattened.
    fn unit(&mut self, unit: &Unit, keep: bool, instanced: &mut Vec<InstancedMesh>) -> Result<(), Located> {
        let mut slot = None;
        for placement in &unit.placements {
            let placer = self.prim(&placement.placer);
            let object_to_world = if keep { affine(&placement.world) } else { None };
            let Some(object_to_world) = object_to_world else {
                // Flattened (by the policy, or a placement that is no valid instance transform, rule V42).
                for mesh in &unit.meshes {
                    self.add(mesh, placement.world * mesh.transform, Some(placer), placement.instance)?;
                }
                self.builder.report.mesh_placements += unit.meshes.len() as u64;
                continue;
            };
            let slot = match slot {
                Some(slot) => slot,
                None => {
                    let start = self.builder.triangle_count();
                    for mesh in &unit.meshes {
                        self.add(mesh, mesh.transform, None, None)?;
                    }
                    let triangles = start..self.builder.triangle_count();
                    let mesh_index = self.prim(&unit.root);
                    instanced.push(InstancedMesh { mesh_index, triangles, placements: Vec::new() });
                    *slot.insert(instanced.len() - 1)
                }
            };
            self.builder.report.mesh_placements += unit.meshes.len() as u64;
            instanced[slot].placements.push(MeshPlacement {
                object_to_world,
                node_index: placer,
                gpu_instance_index: placement.instance.unwrap_or(NO_INDEX),
                moving: false,
            });
        }
        Ok(())
    }

    /// Adds mesh `mesh` placed by `transform`, named as placed by `placer` (and its point-instancer instance).
    fn add(
        &mut self,
        mesh: &PlacedMesh,
        transform: DMat4,
        placer: Option<u32>,
        instance: Option<u32>,
    ) -> Result<(), Located> {
        let first_use = !self.read.contains_key(&mesh.path);
        if first_use {
            let mut geometry =
                mesh::read(&self.stage.prim(mesh.path.as_str()), self.time).map_err(|e| at(&mesh.path, e))?;
            if let Some(skinned) =
                skel::skin(self.stage, &mesh.path, &geometry.points, self.time).map_err(|e| at(&mesh.path, e))?
            {
                geometry.points = skinned.points;
                geometry.skeleton_to_world = Some(skinned.skeleton_to_world);
            }
            self.read.insert(mesh.path.clone(), geometry);
        }
        let mesh_index = self.prim(&mesh.path);
        let geometry = &self.read[&mesh.path];
        // A skinned mesh is placed by its skeleton, wherever the mesh stands.
        let transform = geometry.skeleton_to_world.unwrap_or(transform);
        if !transform.is_finite() {
            return Err(at(&mesh.path, "its world transform is not finite".to_string()));
        }
        let world: Vec<[f32; 3]> = geometry
            .points
            .iter()
            .map(|p| transform.transform_point3(glam::DVec3::from_array(*p)).as_vec3().to_array())
            .collect();
        let provenance = Provenance {
            node_index: placer.unwrap_or(NO_INDEX),
            mesh_index,
            primitive_index: NO_INDEX,
            instance_index: instance.unwrap_or(NO_INDEX),
        };
        let points = &geometry.points;
        self.builder
            .add(PrimitiveInstance {
                provenance,
                vertex_count: points.len(),
                source_position: |v| points[v as usize],
                position: |v| world[v as usize],
                triangles: &geometry.triangles,
                source_vertex_index: None,
                flip_winding: transform.determinant() < 0.0,
                first_use,
                cut_out: false,
                deforming: geometry.skeleton_to_world.is_some(),
            })
            .map_err(|(kind, e)| Located::of_kind(kind, &format!("prim {}", mesh.path), e))?;
        Ok(())
    }
}
