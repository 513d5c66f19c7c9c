//! The tracers a view makes: the fastest kernel for the file on this machine, or a chosen one.

use crate::open::view::BvhView;
use crate::simd::KernelPath;
use crate::tracer::Tracer;
use crate::wide::WideTracer;

impl<'a> BvhView<'a> {
    /// The fastest traversal kernel for this file on this machine: the wide kernel on the best SIMD path when
    /// the file has wide sections, the binary kernel otherwise. Both report the same closest `t` and any-hit
    /// answers (the tests check it); triangle indices refer to the triangles section either way. In a
    /// two-level file the tracer walks the instances and runs that kernel in their meshes.
    ///
    /// Tracing never panics or loops forever, whatever the bytes; on a file that fails [`BvhView::verify`] the
    /// hits it returns are unspecified.
    pub fn tracer(&self) -> Tracer<'a> {
        self.tracer_on(KernelPath::best())
    }

    /// The binary kernel over the nodes and triangles sections: the reference traversal.
    pub fn binary_tracer(&self) -> Tracer<'a> {
        let tracer = Tracer::new(self.nodes(), self.triangles(), self.triangle_ids())
            .with_triangle_flags(self.triangle_flags())
            .with_split_references(self.has_split_references());
        match self.two_level() {
            Some(sections) => tracer.with_instances(sections),
            None => tracer,
        }
    }

    /// The wide kernel on `path` (the portable one where `path` is not supported) through the instances of a
    /// two-level file, or the binary kernel's where the file has no wide sections. In a one-level file,
    /// [`BvhView::tracer`] on `path`'s wide kernel alone is [`BvhView::wide_tracer`].
    pub fn tracer_on(&self, path: KernelPath) -> Tracer<'a> {
        match self.wide_tracer(path) {
            Some(wide) => self.binary_tracer().with_wide(wide),
            None => self.binary_tracer(),
        }
    }

    /// The wide kernel on `path` (the portable one where `path` is not supported), when the file has wide
    /// sections. Over a two-level file it traces the sections as one tree, which they are not: use
    /// [`BvhView::tracer_on`] there.
    pub fn wide_tracer(&self, path: KernelPath) -> Option<WideTracer<'a>> {
        let wide = self.wide_sections()?;
        let root = self.nodes().first()?;
        let tracer = WideTracer::over(wide.nodes, wide.packets, (root.min, root.max), self.triangle_ids(), path);
        Some(tracer.with_split_references(self.has_split_references()))
    }
}
