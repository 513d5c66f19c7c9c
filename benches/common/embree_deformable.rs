//! An Embree scene a benchmark deforms (a submodule of `embree.rs`, whose declarations it shares): one triangle
//! geometry whose vertex buffer is rewritten and committed again, as a renderer updates a skinned mesh each
//! frame, with Embree's refit (`RTC_BUILD_QUALITY_REFIT`) or its fastest rebuild (`RTC_BUILD_QUALITY_LOW`) on a
//! device of a given thread count.

use super::{
    BUFFER_TYPE_INDEX, BUFFER_TYPE_VERTEX, Device, FORMAT_FLOAT3, FORMAT_UINT3, GEOMETRY_TYPE_TRIANGLE, Geometry,
    Scene, rtcAttachGeometry, rtcCommitGeometry, rtcCommitScene, rtcNewDevice, rtcNewGeometry, rtcNewScene,
    rtcReleaseDevice, rtcReleaseGeometry, rtcReleaseScene, rtcSetGeometryBuildQuality, rtcSetNewGeometryBuffer,
    rtcSetSceneBuildQuality, rtcSetSceneFlags,
};
use std::os::raw::c_uint;

#[cfg_attr(not(feature = "embree4"), link(name = "embree3"))]
#[cfg_attr(feature = "embree4", link(name = "embree4"))]
unsafe extern "C" {
    fn rtcUpdateGeometryBuffer(geometry: Geometry, kind: c_uint, slot: c_uint);
}

const BUILD_QUALITY_LOW: c_uint = 0;
const BUILD_QUALITY_REFIT: c_uint = 3;
const SCENE_FLAG_DYNAMIC: c_uint = 1;

/// How Embree updates the deformed scene.
#[derive(Clone, Copy, Debug)]
pub enum Update {
    /// `RTC_BUILD_QUALITY_REFIT` on the geometry (in a LOW, dynamic scene): its BVH built once, then refit.
    Refit,
    /// `RTC_BUILD_QUALITY_LOW` on the geometry and the scene, `RTC_SCENE_FLAG_DYNAMIC`: rebuilt each commit by
    /// Embree's fastest builder.
    LowRebuild,
}

/// One committed triangle geometry whose vertices [`Deformable::update`] moves.
pub struct Deformable {
    device: Device,
    scene: Scene,
    geometry: Geometry,
    vertices: *mut f32,
    triangle_count: usize,
}

impl Deformable {
    /// The scene over `triangles`, updated the `update` way on `threads` threads.
    pub fn new(triangles: &[[[f32; 3]; 3]], update: Update, threads: usize) -> Deformable {
        let config = std::ffi::CString::new(format!("threads={threads},isa={}", super::max_isa())).expect("no NUL");
        // SAFETY: the config string lives for the call; every handle is checked for null and released once in
        // `drop` (the geometry kept alive for the updates); the buffers are sized by the counts passed.
        unsafe {
            let device = rtcNewDevice(config.as_ptr());
            assert!(!device.is_null(), "rtcNewDevice failed");
            let scene = rtcNewScene(device);
            // Embree reads a geometry's build quality only in a scene of LOW quality (a two-level structure
            // whose geometries build their own BVHs): so both ways use one.
            let geometry_quality = match update {
                Update::Refit => BUILD_QUALITY_REFIT,
                Update::LowRebuild => BUILD_QUALITY_LOW,
            };
            rtcSetSceneBuildQuality(scene, BUILD_QUALITY_LOW);
            rtcSetSceneFlags(scene, SCENE_FLAG_DYNAMIC);
            let geometry = rtcNewGeometry(device, GEOMETRY_TYPE_TRIANGLE);
            assert!(!geometry.is_null(), "rtcNewGeometry failed");
            rtcSetGeometryBuildQuality(geometry, geometry_quality);
            let n = triangles.len();
            let vertices =
                rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_VERTEX, 0, FORMAT_FLOAT3, 12, 3 * n) as *mut f32;
            let indices = rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3, 12, n) as *mut u32;
            assert!(!vertices.is_null() && !indices.is_null(), "rtcSetNewGeometryBuffer failed");
            let indices = std::slice::from_raw_parts_mut(indices, 3 * n);
            indices.iter_mut().enumerate().for_each(|(k, index)| *index = k as u32);
            let mut deformable = Deformable { device, scene, geometry, vertices, triangle_count: n };
            deformable.write(triangles);
            rtcCommitGeometry(geometry);
            rtcAttachGeometry(scene, geometry);
            rtcCommitScene(scene);
            deformable
        }
    }

    fn write(&mut self, triangles: &[[[f32; 3]; 3]]) {
        assert_eq!(triangles.len(), self.triangle_count);
        // SAFETY: `vertices` is Embree's buffer of `9 * triangle_count` floats, alive with the geometry.
        let vertices = unsafe { std::slice::from_raw_parts_mut(self.vertices, 9 * self.triangle_count) };
        vertices.copy_from_slice(triangles.as_flattened().as_flattened());
    }

    /// Moves the vertices to `triangles` and commits: the scene's BVH refit or rebuilt.
    pub fn update(&mut self, triangles: &[[[f32; 3]; 3]]) {
        self.write(triangles);
        // SAFETY: live handles; the buffer was written in place.
        unsafe {
            rtcUpdateGeometryBuffer(self.geometry, BUFFER_TYPE_VERTEX, 0);
            rtcCommitGeometry(self.geometry);
            rtcCommitScene(self.scene);
        }
    }
}

impl Drop for Deformable {
    fn drop(&mut self) {
        // SAFETY: each handle came from `new` and is released once, the geometry and scene before the device.
        unsafe {
            rtcReleaseGeometry(self.geometry);
            rtcReleaseScene(self.scene);
            rtcReleaseDevice(self.device);
        }
    }
}
