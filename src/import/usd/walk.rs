//! The walk over a composed stage: which meshes USD's renderers draw and where, before any mesh is read.
//!
//! Prims come in the stage's depth-first order (instance proxies included). Each inherits its parent's world
//! transform (unless it resets the stack), visibility (an `invisible` prim hides its subtree) and purpose (the
//! nearest authored one, else `default`). A mesh of a kept purpose is drawn where it stands; a native instance
//! (an instanceable prim) and each `PointInstancer` prototype become a [`Unit`]: the meshes of one subtree in
//! the subtree's own space, and the placements of that subtree. Instances of one prototype (with the same
//! inherited purpose) share a unit. A point instancer's subtree is drawn only through its prototypes, as
//! Hydra draws it.

use std::collections::HashMap;

use glam::{DMat4, DVec3};
use openusd::sdf::{self, Value};
use openusd::usd::{Stage, TimeCode};

use super::mesh::{int_array, points_array, token};
use super::xform::{local_transform, value_kind};
use crate::import::{ImportOptions, Located};

/// A mesh prim and its transform (world space, or a unit's own space).
pub(super) struct PlacedMesh {
    pub path: String,
    pub transform: DMat4,
}

/// One placement of a unit.
pub(super) struct Placement {
    pub world: DMat4,
    /// The prim that places it: the instance prim, or the point instancer.
    pub placer: String,
    /// The point instancer's instance index, where it is one.
    pub instance: Option<u32>,
}

/// A subtree drawn at several places: its meshes in its own space and its placements.
pub(super) struct Unit {
    /// The prototype's root: the first instance prim, or the point instancer's prototype prim.
    pub root: String,
    pub meshes: Vec<PlacedMesh>,
    pub placements: Vec<Placement>,
}

/// What the stage draws.
#[derive(Default)]
pub(super) struct Scene {
    pub meshes: Vec<PlacedMesh>,
    pub units: Vec<Unit>,
}

#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
enum Purpose {
    Default,
    Render,
    Proxy,
    Guide,
}

/// What a prim passes to its children.
#[derive(Clone, Copy)]
struct Inherited {
    transform: DMat4,
    purpose: Purpose,
}

/// Walks `paths` (the stage's prims in depth-first order) at `time`.
pub(super) fn collect(
    stage: &Stage,
    paths: &[sdf::Path],
    time: Option<TimeCode>,
    options: &ImportOptions,
) -> Result<Scene, Located> {
    let walker = Walker { stage, paths, time, keep: options.purposes };
    let mut scene = Scene::default();
    let mut unit_of_prototype: HashMap<(String, Purpose), usize> = HashMap::new();
    let mut state: HashMap<&str, Inherited> = HashMap::new();
    let root = Inherited { transform: DMat4::IDENTITY, purpose: Purpose::Default };
    let mut index = 0;
    while index < paths.len() {
        let path = &paths[index];
        let text = path.as_str();
        let parent = match path.parent() {
            Some(p) if p.as_str() != "/" => match state.get(p.as_str()) {
                Some(inherited) => *inherited,
                None => {
                    index += 1;
                    continue; // under a hidden prim, an instance or a point instancer: drawn elsewhere or not at all
                }
            },
            _ => root,
        };
        let at = |e: String| Located::new(&format!("prim {text}"), e);
        let Some(here) = walker.inherit(path, parent, false).map_err(at)? else {
            index += 1;
            continue;
        };
        let prim = stage.prim(path.clone());
        let kind = type_name(stage, path);
        if kind == "PointInstancer" {
            walker.point_instancer(path, here, &mut scene).map_err(at)?;
            index = walker.subtree_end(index);
            continue;
        }
        if prim.is_instance().unwrap_or(false) {
            let end = walker.subtree_end(index);
            // Instances share a unit by prototype; one whose prototype the reader cannot name has its own.
            let prototype = match prim.prototype() {
                Ok(Some(prototype)) => prototype.as_str().to_string(),
                _ => text.to_string(),
            };
            let key = (prototype, here.purpose);
            let slot = match unit_of_prototype.get(&key) {
                Some(&slot) => slot,
                None => {
                    let meshes = walker.gather(index, end, here.purpose, false)?;
                    scene.units.push(Unit { root: text.to_string(), meshes, placements: Vec::new() });
                    unit_of_prototype.insert(key, scene.units.len() - 1);
                    scene.units.len() - 1
                }
            };
            scene.units[slot].placements.push(Placement {
                world: here.transform,
                placer: text.to_string(),
                instance: None,
            });
            index = end;
            continue;
        }
        if kind == "Mesh" && walker.keeps(here.purpose) {
            scene.meshes.push(PlacedMesh { path: text.to_string(), transform: here.transform });
        }
        state.insert(text, here);
        index += 1;
    }
    Ok(scene)
}

struct Walker<'a> {
    stage: &'a Stage,
    paths: &'a [sdf::Path],
    time: Option<TimeCode>,
    keep: super::super::Purposes,
}

impl Walker<'_> {
    fn keeps(&self, purpose: Purpose) -> bool {
        match purpose {
            Purpose::Default => true,
            Purpose::Render => self.keep.render,
            Purpose::Proxy => self.keep.proxy,
            Purpose::Guide => self.keep.guide,
        }
    }

    /// The index after the subtree of the prim at `index` (the paths are in depth-first order).
    fn subtree_end(&self, index: usize) -> usize {
        let prefix = format!("{}/", self.paths[index].as_str());
        let mut end = index + 1;
        while end < self.paths.len() && self.paths[end].as_str().starts_with(&prefix) {
            end += 1;
        }
        end
    }

    /// What the prim at `path` passes on, from its parent's; `None` when it is invisible. `own_space`: the prim
    /// is a unit's root, whose own transform is its placement's (so the unit's space starts at the identity).
    fn inherit(&self, path: &sdf::Path, parent: Inherited, own_space: bool) -> Result<Option<Inherited>, String> {
        let prim = self.stage.prim(path.clone());
        if let Some(Value::Token(v)) =
            prim.attribute("visibility").get_at::<Value>(self.time).map_err(|e| e.to_string())?
            && v.as_str() == "invisible"
        {
            return Ok(None);
        }
        let purpose = match token(&prim, "purpose")?.as_deref() {
            None => parent.purpose,
            Some("default") => Purpose::Default,
            Some("render") => Purpose::Render,
            Some("proxy") => Purpose::Proxy,
            Some("guide") => Purpose::Guide,
            Some(other) => return Err(format!("purpose '{other}' is not one USD defines")),
        };
        let transform = if own_space {
            DMat4::IDENTITY
        } else {
            let local = local_transform(&prim, self.time)?;
            if local.resets_stack { local.matrix } else { parent.transform * local.matrix }
        };
        Ok(Some(Inherited { transform, purpose }))
    }

    /// The meshes of the subtree `start..end` in the space of its root (whose own transform is left out when
    /// `include_root` is false), of the kept purposes, visible ones only.
    fn gather(
        &self,
        start: usize,
        end: usize,
        purpose: Purpose,
        include_root: bool,
    ) -> Result<Vec<PlacedMesh>, Located> {
        let mut meshes = Vec::new();
        let mut state: HashMap<&str, Inherited> = HashMap::new();
        for path in &self.paths[start..end] {
            let text = path.as_str();
            let at = |e: String| Located::new(&format!("prim {text}"), e);
            let is_root = text == self.paths[start].as_str();
            let parent = if is_root {
                Inherited { transform: DMat4::IDENTITY, purpose }
            } else {
                match path.parent().and_then(|p| state.get(p.as_str()).copied()) {
                    Some(parent) => parent,
                    None => continue,
                }
            };
            let Some(here) = self.inherit(path, parent, is_root && !include_root).map_err(at)? else { continue };
            let kind = type_name(self.stage, path);
            if kind == "PointInstancer" {
                return Err(at("a PointInstancer inside an instance or a prototype is not supported".to_string()));
            }
            if kind == "Mesh" && self.keeps(here.purpose) {
                meshes.push(PlacedMesh { path: text.to_string(), transform: here.transform });
            }
            state.insert(text, here);
        }
        Ok(meshes)
    }

    /// A point instancer at `path`: one unit a prototype, its placements the instances that draw it.
    fn point_instancer(&self, path: &sdf::Path, here: Inherited, scene: &mut Scene) -> Result<(), String> {
        let prim = self.stage.prim(path.clone());
        let targets = prim.relationship("prototypes").targets().map_err(|e| format!("prototypes: {e}"))?;
        let indices = int_array(&prim, "protoIndices", self.time)?;
        let positions = points_array(&prim, "positions", self.time)?.unwrap_or_default();
        if positions.len() != indices.len() {
            return Err(format!("{} protoIndices but {} positions", indices.len(), positions.len()));
        }
        let orientations = orientations(&prim, self.time)?;
        let scales = points_array(&prim, "scales", self.time)?;
        let ids = prim.attribute("ids").get_at::<Value>(self.time).map_err(|e| format!("ids: {e}"))?;
        let invisible =
            prim.attribute("invisibleIds").get_at::<Value>(self.time).map_err(|e| format!("invisibleIds: {e}"))?;
        let ids = id_list(ids, "ids")?;
        let invisible = id_list(invisible, "invisibleIds")?.unwrap_or_default();
        let count = indices.len();
        if orientations.as_ref().is_some_and(|o| o.len() != count) || scales.as_ref().is_some_and(|s| s.len() != count)
        {
            return Err(format!("orientations or scales do not have one value for each of the {count} instances"));
        }
        if ids.as_ref().is_some_and(|i| i.len() != count) {
            return Err(format!("ids do not have one value for each of the {count} instances"));
        }
        let mut units = Vec::new();
        for target in &targets {
            let start = self
                .paths
                .iter()
                .position(|p| p == target)
                .ok_or_else(|| format!("prototype {} is not an active, defined prim", target.as_str()))?;
            let meshes =
                self.gather(start, self.subtree_end(start), here.purpose, true).map_err(|e| e.message().to_string())?;
            units.push(Unit { root: target.as_str().to_string(), meshes, placements: Vec::new() });
        }
        for (i, &proto) in indices.iter().enumerate() {
            let id = ids.as_ref().map_or(i as i64, |ids| ids[i]);
            if invisible.contains(&id) {
                continue;
            }
            let unit = usize::try_from(proto)
                .ok()
                .and_then(|p| units.get_mut(p))
                .ok_or_else(|| format!("protoIndices[{i}] = {proto} names no prototype ({} targets)", targets.len()))?;
            let p = positions[i];
            let rotation = orientations.as_ref().map_or(glam::DQuat::IDENTITY, |o| o[i]);
            let scale = scales.as_ref().map_or(DVec3::ONE, |s| DVec3::from_array(s[i]));
            let instance = DMat4::from_scale_rotation_translation(scale, rotation, DVec3::from_array(p));
            unit.placements.push(Placement {
                world: here.transform * instance,
                placer: path.as_str().to_string(),
                instance: Some(i as u32),
            });
        }
        scene.units.extend(units.into_iter().filter(|u| !u.placements.is_empty()));
        Ok(())
    }
}

/// A prim's type name ("" for a typeless prim).
fn type_name(stage: &Stage, path: &sdf::Path) -> String {
    stage.prim(path.clone()).type_name().ok().flatten().map(|t| t.as_str().to_string()).unwrap_or_default()
}

/// A point instancer's `orientations` (quath) or `orientationsf` (quatf), the latter preferred where authored,
/// as authored: USD's point instancer turns each into a matrix by the unit-quaternion formula without
/// normalizing it first (a half-precision quaternion is a little off unit length), and so does this import.
fn orientations(prim: &openusd::usd::Prim, time: Option<TimeCode>) -> Result<Option<Vec<glam::DQuat>>, String> {
    for name in ["orientationsf", "orientations"] {
        let rotations = match prim.attribute(name).get_at::<Value>(time).map_err(|e| format!("{name}: {e}"))? {
            None => continue,
            Some(Value::QuathVec(q)) => q
                .iter()
                .map(|q| {
                    raw_quaternion(q.w.to_f32().into(), q.x.to_f32().into(), q.y.to_f32().into(), q.z.to_f32().into())
                })
                .collect::<Result<Vec<_>, _>>(),
            Some(Value::QuatfVec(q)) => q
                .iter()
                .map(|q| raw_quaternion(q.w.into(), q.x.into(), q.y.into(), q.z.into()))
                .collect::<Result<Vec<_>, _>>(),
            Some(other) => return Err(format!("{name} holds {}, not quaternions", value_kind(&other))),
        };
        return rotations.map(Some).map_err(|e| format!("{name}: {e}"));
    }
    Ok(None)
}

/// A quaternion (real part first) as authored; refused when not finite.
fn raw_quaternion(w: f64, x: f64, y: f64, z: f64) -> Result<glam::DQuat, String> {
    let q = glam::DQuat::from_xyzw(x, y, z, w);
    if q.is_finite() { Ok(q) } else { Err(format!("the quaternion ({w}, {x}, {y}, {z}) is not finite")) }
}

/// An `int64[]` (or `int[]`) id list.
fn id_list(value: Option<Value>, name: &str) -> Result<Option<Vec<i64>>, String> {
    match value {
        None => Ok(None),
        Some(Value::Int64Vec(v)) => Ok(Some(v)),
        Some(Value::IntVec(v)) => Ok(Some(v.into_iter().map(i64::from).collect())),
        Some(other) => Err(format!("{name} holds {}, not ids", value_kind(&other))),
    }
}
