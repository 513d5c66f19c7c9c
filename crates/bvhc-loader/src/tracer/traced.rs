//! [`TracedFile`]: an owned file together with its tracer, made once, for bindings that keep one handle per
//! file and trace through it call after call (the C API, a Python module). Making a [`Tracer`] from a
//! [`BvhFile`] reads the section table again (`BvhFile::view`), tens of nanoseconds: nothing for a batch, a
//! quarter of a single ray's time.

use crate::open::file::BvhFile;
use crate::open::view::BvhView;
use crate::tracer::Tracer;

/// A [`BvhFile`] and the tracer over it ([`BvhView::tracer`]), made once.
pub struct TracedFile {
    /// Borrows from `file`'s buffer: declared first, so it is dropped before `file`. Its `'static` never leaves
    /// this struct: [`TracedFile::tracer`] hands it out for the borrow of `self` only.
    tracer: Tracer<'static>,
    file: BvhFile,
}

impl TracedFile {
    /// `file` with its fastest tracer (the wide kernel on the best path, through the instances of a two-level
    /// file).
    #[allow(unsafe_code)] // the lifetime of the tracer's borrow, see the SAFETY note
    pub fn new(file: BvhFile) -> TracedFile {
        let tracer = file.view().tracer();
        // SAFETY: the tracer borrows slices of `file`'s heap buffer (`AlignedBuffer`), which `file` owns, never
        // changes after opening and frees only when dropped; moving `file` into the struct moves the buffer's
        // pointer, not its bytes. The struct drops `tracer` before `file`, and never exposes the `'static`
        // lifetime: `tracer()` narrows it to the borrow of `self`, during which `file` lives.
        let tracer = unsafe { std::mem::transmute::<Tracer<'_>, Tracer<'static>>(tracer) };
        TracedFile { tracer, file }
    }

    /// This file with its tracer trusting rays ([`Tracer::trusting_rays`]): for bindings that check rays
    /// themselves to report an error rather than panic.
    pub fn trusting_rays(self) -> TracedFile {
        TracedFile { tracer: self.tracer.trusting_rays(), file: self.file }
    }

    /// The tracer, made when this was.
    pub fn tracer(&self) -> &Tracer<'_> {
        &self.tracer
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
        f.debug_struct("TracedFile").field("file", &self.file).field("kernel", &self.tracer.kernel()).finish()
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
}
