//! Hit filters from Python (the loader's `HitFilter`, `format-spec/bvh-1.md` 11.5). Two forms:
//! * **cut-out masks**, applied in Rust with no Python call per candidate, so tracing keeps every core: a boolean
//!   array over source ids (`cutout[source_id]` true: that triangle is cut out, as if absent) and a list of
//!   `(mesh, primitive)` pairs whose triangles are cut out (a glTF material made invisible);
//! * a **callback** `filter(ray, t, u, v, triangle, source_id, instance) -> bool` (the ray's index in the call;
//!   true accepts the candidate), for the rest: called from the calling thread with the GIL, one candidate at a
//!   time, so a call with a callback traces on one thread. An exception it raises ends the call with that
//!   exception (candidates after it are accepted, their results discarded).
//!
//! Masks come first: a candidate they cut out is never shown to the callback. `filter_scope` says which
//! candidates are asked at all: `"every"` (the default), or `"not_opaque"`, only those on triangles the file marks
//! not opaque (glTF `MASK`/`BLEND` materials), every other hit accepted at once.

use std::cell::{Cell, RefCell};

use bvhc::loader::format::SourceRange;
use bvhc::loader::{BvhView, HitFilter, PointCandidate, PointFilter, filter::Candidate, filter::FilterScope};
use numpy::{PyReadonlyArray1, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::InvalidInputError;

/// A filter's arguments as the Python call gave them.
pub struct FilterArgs<'py> {
    cutout: Option<PyReadonlyArray1<'py, bool>>,
    primitives: Option<Vec<(u32, u32)>>,
    pub callback: Option<Bound<'py, PyAny>>,
    pub scope: FilterScope,
}

impl<'py> FilterArgs<'py> {
    /// The filter of a call, or `None` when it gives none.
    pub fn extract(
        cutout: Option<Bound<'py, PyAny>>,
        cutout_primitives: Option<Bound<'py, PyAny>>,
        callback: Option<Bound<'py, PyAny>>,
        scope: &str,
    ) -> PyResult<Option<FilterArgs<'py>>> {
        let scope = match scope {
            "every" => FilterScope::Every,
            "not_opaque" => FilterScope::NotOpaque,
            other => {
                let why = format!("filter_scope: {other:?}; expected \"every\" or \"not_opaque\"");
                return Err(InvalidInputError::new_err(why));
            }
        };
        let cutout = cutout
            .map(|c| {
                c.extract::<PyReadonlyArray1<'py, bool>>().map_err(|_| {
                    InvalidInputError::new_err("cutout: expected a one-dimensional numpy array of dtype bool")
                })
            })
            .transpose()?;
        let primitives = cutout_primitives
            .map(|p| {
                p.extract::<Vec<(u32, u32)>>().map_err(|_| {
                    InvalidInputError::new_err("cutout_primitives: expected pairs (mesh, primitive) of integers")
                })
            })
            .transpose()?;
        if let Some(callback) = &callback
            && !callback.is_callable()
        {
            return Err(InvalidInputError::new_err("filter: expected a callable"));
        }
        let any = cutout.is_some() || primitives.is_some() || callback.is_some();
        Ok(any.then_some(FilterArgs { cutout, primitives, callback, scope }))
    }

    /// The masks over `view`'s source ids and ranges, checked against the file.
    pub fn cutouts<'a>(&'a self, view: &BvhView<'a>) -> PyResult<Cutouts<'a>> {
        let table = view.source_table().unwrap_or_default();
        let by_source_id = match &self.cutout {
            Some(mask) => {
                if view.triangle_ids().is_none() {
                    return Err(InvalidInputError::new_err(
                        "cutout: the file has no source ids to index it by (convert without --no-ids)",
                    ));
                }
                let needed = source_id_count(view);
                if mask.len() != needed {
                    let why = format!("cutout: {} values for the file's {needed} source ids", mask.len());
                    return Err(InvalidInputError::new_err(why));
                }
                Some(mask.as_slice().map_err(|e| InvalidInputError::new_err(format!("cutout: {e}")))?)
            }
            None => None,
        };
        let by_range = match &self.primitives {
            Some(pairs) => {
                if table.is_empty() {
                    return Err(InvalidInputError::new_err(
                        "cutout_primitives: the file has no source table naming meshes and primitives",
                    ));
                }
                table.iter().map(|r| pairs.contains(&(r.mesh_index, r.primitive_index))).collect()
            }
            None => Vec::new(),
        };
        Ok(Cutouts { by_source_id, by_range, table })
    }
}

/// Source ids of a file: the end of its last source range, or one past its largest id.
pub fn source_id_count(view: &BvhView<'_>) -> usize {
    match (view.source_table(), view.triangle_ids()) {
        (Some(table), _) if !table.is_empty() => {
            table.last().map_or(0, |r| r.first_source_triangle as usize + r.source_triangle_count as usize)
        }
        (_, Some(ids)) => ids.iter().max().map_or(0, |&m| m as usize + 1),
        _ => 0,
    }
}

/// The cut-out masks: `Send + Sync`, applied on every thread.
pub struct Cutouts<'a> {
    by_source_id: Option<&'a [bool]>,
    /// Per source range, whether its triangles are cut out (empty: no primitive is).
    by_range: Vec<bool>,
    table: &'a [SourceRange],
}

impl Cutouts<'_> {
    /// Whether the triangle of source id `id` is cut out (one with no source id never is).
    fn cuts(&self, id: Option<u32>) -> bool {
        let Some(id) = id else { return false };
        if self.by_source_id.is_some_and(|mask| mask.get(id as usize) == Some(&true)) {
            return true;
        }
        if !self.by_range.is_empty() {
            let after = self.table.partition_point(|r| r.first_source_triangle <= id);
            if after > 0 && self.by_range[after - 1] {
                return true;
            }
        }
        false
    }
}

impl HitFilter for Cutouts<'_> {
    fn accept(&self, candidate: &Candidate<'_>) -> bool {
        !self.cuts(candidate.source_triangle_id)
    }
}

/// The same masks on point queries: a cut-out triangle is never the closest.
impl PointFilter for Cutouts<'_> {
    fn keep(&self, candidate: &PointCandidate) -> bool {
        !self.cuts(candidate.source_triangle_id)
    }
}

/// The masks and a Python callback, on the calling thread with the GIL held; the index of the ray being traced
/// is set before each ray.
pub struct WithCallback<'a, 'py> {
    pub cutouts: &'a Cutouts<'a>,
    pub callback: &'a Bound<'py, PyAny>,
    pub ray: Cell<usize>,
    pub error: RefCell<Option<PyErr>>,
}

impl HitFilter for WithCallback<'_, '_> {
    fn accept(&self, candidate: &Candidate<'_>) -> bool {
        if !self.cutouts.accept(candidate) {
            return false;
        }
        if self.error.borrow().is_some() {
            return true;
        }
        let missing = u32::MAX;
        let arguments = (
            self.ray.get(),
            candidate.t,
            candidate.u,
            candidate.v,
            candidate.triangle_index,
            candidate.source_triangle_id.unwrap_or(missing),
            candidate.instance_index.unwrap_or(missing),
        );
        match self.callback.call1(arguments).and_then(|answer| answer.is_truthy()) {
            Ok(accepted) => accepted,
            Err(error) => {
                *self.error.borrow_mut() = Some(error);
                true
            }
        }
    }
}
