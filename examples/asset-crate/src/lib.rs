//! Example: a `.bvh` file produced by this crate's build script and embedded in the binary.

use bvhc_loader::BvhFile;

/// The teapot's `.bvh` bytes, converted at build time.
pub static TEAPOT_BVH: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/teapot.bvh"));

/// The embedded teapot, copied into an aligned buffer and opened.
pub fn teapot() -> Result<BvhFile, bvhc_loader::Error> {
    BvhFile::from_bytes(TEAPOT_BVH)
}

#[cfg(test)]
mod tests {
    use bvhc_loader::{Ray, Trace};

    use super::*;

    #[test]
    fn the_embedded_teapot_verifies_and_is_hit() {
        let file = teapot().expect("the build script wrote a valid file");
        let view = file.view();
        view.verify().expect("every rule holds");
        assert_eq!(view.triangles().len(), 6320);
        let root = view.nodes()[0];
        let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (root.min[a] + root.max[a]));
        let hit = view.tracer().closest_hit(&Ray::new([center[0], center[1], 100.0], [0.0, 0.0, -1.0]));
        assert!(hit.is_some_and(|h| h.source_triangle_id.is_some()));
    }
}
