//! [`TracedFile`]: an owned file together with its tracer, made once, for bindings that keep one handle per
//! file and trace through it call after call (the C API, a Python module). Making a [`Tracer`] from a
//! [`BvhFile`] reads the section table again (`BvhFile::view`), tens of nanoseconds: nothing for a batch, a
//! quarter of a single ray's time.

use crate::open::file::BvhFile;
use crate::open::view::BvhView;
use crate::tracer::Tracer;
use crate::tracer::winding::{WindingMoments, WindingNumbers};
use std::collections::TryReserveError;
use std::sync::{Arc, Mutex, PoisonError};

/// A [`BvhFile`] and the tracer over it ([`BvhView::tracer`]), made once.
pub struct TracedFile {
    /// Borrows from `file`'s buffer: declared first, so it is dropped before `file`. Its `'static` never leaves
    /// this struct: [`TracedFile::tracer`] hands it out for the borrow of `self` only. While
    /// [`TracedFile::edit_file`] changes the buffer it is a tracer over no triangles, which borrows nothing.
    tracer: Tracer<'static>,
    file: BvhFile,
    /// The file's winding moments, once a call has asked for them; dropped by [`TracedFile::edit_file`].
    winding: Mutex<Option<Arc<WindingMoments>>>,
}

/// A tracer over `file` with its lifetime widened to `'static`, which [`TracedFile`] keeps (see its fields).
#[allow(unsafe_code)] // the lifetime of the tracer's borrow, see the SAFETY note
fn kept_tracer(file: &BvhFile, checks_rays: bool) -> Tracer<'static> {
    let tracer = file.view().tracer();
    let tracer = if checks_rays { tracer } else { tracer.trusting_rays() };
    // SAFETY: the tracer borrows slices of `file`'s heap buffer (`AlignedBuffer`), which `file` owns, changes
    // only inside `TracedFile::edit_file` (which drops this tracer first and makes a new one after) and frees
    // only when dropped; moving `file` into the struct moves the buffer's pointer, not its bytes. The struct
    // drops `tracer` before `file`, and never exposes the `'static` lifetime: `tracer()` narrows it to the
    // borrow of `self`, during which `file` lives and does not change.
    unsafe { std::mem::transmute::<Tracer<'_>, Tracer<'static>>(tracer) }
}

impl TracedFile {
    /// `file` with its fastest tracer (the wide kernel on the best path, through the instances of a two-level
    /// file).
    pub fn new(file: BvhFile) -> TracedFile {
        TracedFile { tracer: kept_tracer(&file, true), file, winding: Mutex::new(None) }
    }

    /// This file with its tracer trusting rays ([`Tracer::trusting_rays`]): for bindings that check rays
    /// themselves to report an error rather than panic.
    pub fn trusting_rays(self) -> TracedFile {
        TracedFile { tracer: self.tracer.trusting_rays(), ..self }
    }

    /// The tracer, made when this was (or after the last [`TracedFile::edit_file`]).
    pub fn tracer(&self) -> &Tracer<'_> {
        &self.tracer
    }

    /// Runs `edit` on the file (a refit, moved instances: [`BvhFile::refit`], [`BvhFile::move_instances`]) and
    /// makes the tracer again over the changed bytes, checking rays or not as before. Taking `&mut self`, it
    /// cannot overlap a trace through this file.
    pub fn edit_file<R>(&mut self, edit: impl FnOnce(&mut BvhFile) -> R) -> R {
        /// Puts a tracer back when dropped, so that even a panic in `edit` leaves one.
        struct Restore<'t> {
            traced: &'t mut TracedFile,
            checks_rays: bool,
        }
        impl Drop for Restore<'_> {
            fn drop(&mut self) {
                self.traced.tracer = kept_tracer(&self.traced.file, self.checks_rays);
            }
        }
        let checks_rays = self.tracer.checks_rays();
        // The moments describe the bytes as they were.
        *self.winding.get_mut().unwrap_or_else(PoisonError::into_inner) = None;
        // No borrow of the buffer may live while it changes.
        self.tracer = Tracer::new(&[], &[], None);
        let restore = Restore { traced: self, checks_rays };
        edit(&mut restore.traced.file)
    }

    /// The file's winding numbers and signed distances ([`WindingNumbers`]), their moments computed by the first
    /// call and kept until the next [`TracedFile::edit_file`]. Fails only when memory for them cannot be had.
    pub fn winding_numbers(&self) -> Result<WindingNumbers<'_>, TryReserveError> {
        let mut kept = self.winding.lock().unwrap_or_else(PoisonError::into_inner);
        let moments = match &*kept {
            Some(moments) => Arc::clone(moments),
            None => Arc::clone(kept.insert(Arc::new(WindingMoments::new(&self.tracer)?))),
        };
        Ok(WindingNumbers::with_moments(self.tracer(), moments))
    }

    /// The file.
    pub fn file(&self) -> &BvhFile {
        &self.file
    }

    /// A view of the file.
    pub fn view(&self) -> BvhView<'_> {
        self.file.view()
    }
}

impl std::fmt::Debug for TracedFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TracedFile").field("file", &self.file).field("kernel", &self.tracer().kernel()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ray::intersect::Ray;
    use crate::trace::Trace;

    #[test]
    fn the_kept_tracer_traces_as_a_fresh_one_after_the_file_moved() {
        let file = BvhFile::from_bytes(include_bytes!("../../tests/data/quad-v1.1.bvh")).unwrap();
        let traced = TracedFile::new(file);
        let moved = Box::new(traced);
        let ray = Ray::new([0.25, 0.75, 1.0], [0.0, 0.0, -1.0]);
        assert_eq!(moved.tracer().closest_hit(&ray), moved.view().tracer().closest_hit(&ray));
        assert_eq!(moved.tracer().closest_hit(&ray).map(|h| h.t), Some(1.0));
    }

    #[test]
    fn an_edit_makes_the_tracer_again_over_the_changed_bytes() {
        let file = BvhFile::from_bytes(include_bytes!("../../tests/data/quad-v1.1.bvh")).unwrap();
        let mut traced = TracedFile::new(file).trusting_rays();
        let ray = Ray::new([0.25, 0.75, 1.0], [0.0, 0.0, -1.0]);
        assert_eq!(traced.tracer().closest_hit(&ray).map(|h| h.t), Some(1.0));
        // The quad lifted by 0.5 towards the ray.
        let lifted: Vec<[[f32; 3]; 3]> =
            traced.view().triangles().iter().map(|t| t.vertices.map(|[x, y, z]| [x, y, z + 0.5])).collect();
        traced.edit_file(|file| file.refit_triangles(&lifted)).unwrap();
        assert_eq!(traced.tracer().closest_hit(&ray).map(|h| h.t), Some(0.5));
        assert!(!traced.tracer().checks_rays(), "still trusting rays");
    }

    #[test]
    fn winding_moments_are_kept_until_an_edit() {
        let file = BvhFile::from_bytes(include_bytes!("../../tests/data/quad-v1.1.bvh")).unwrap();
        let mut traced = TracedFile::new(file);
        let first = Arc::clone(traced.winding_numbers().unwrap().moments());
        assert!(Arc::ptr_eq(&first, traced.winding_numbers().unwrap().moments()), "kept");
        // Above the quad (0..1 square at z = 0) at height 1; after lifting it by 2 the point is below it.
        let lifted: Vec<[[f32; 3]; 3]> =
            traced.view().triangles().iter().map(|t| t.vertices.map(|[x, y, z]| [x, y, z + 2.0])).collect();
        let before = traced.winding_numbers().unwrap().winding_number([0.5, 0.5, 1.0]);
        traced.edit_file(|file| file.refit_triangles(&lifted)).unwrap();
        let after = traced.winding_numbers().unwrap();
        assert!(!Arc::ptr_eq(&first, after.moments()), "computed again after the edit");
        let fresh = traced.tracer().winding_numbers().unwrap().winding_number([0.5, 0.5, 1.0]);
        assert_eq!(after.winding_number([0.5, 0.5, 1.0]), fresh);
        assert!(before * fresh < 0.0, "the open quad's winding number changes sign: {before} then {fresh}");
    }
}
