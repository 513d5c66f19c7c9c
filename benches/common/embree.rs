//! Embree 3 as a benchmark peer, through a small FFI of our own to Debian's `libembree3` (3.13.5;
//! `apt-get install libembree-dev`). Compiled only with `--features embree`, so the default build, the tests and
//! CI never need the library.
//!
//! One triangle mesh per scene, built with `RTC_BUILD_QUALITY_HIGH` (spatial splits), optionally with
//! `RTC_SCENE_FLAG_ROBUST`, or meshes placed by instance geometries (`RTC_GEOMETRY_TYPE_INSTANCE`, a 3x4
//! row-major transform each, Embree's two-level scenes); single rays through `rtcIntersect1` / `rtcOccluded1` and 8-wide packets through
//! `rtcIntersect8` / `rtcOccluded8`. The calling thread gets flush-to-zero and denormals-are-zero, as Embree asks.
#![allow(unsafe_code)] // FFI: every call's contract is stated beside it.
#![allow(dead_code)] // each benchmark uses the part it needs

use std::ffi::c_void;
use std::os::raw::{c_char, c_int, c_uint};

use bvhc::loader::Ray;

type Device = *mut c_void;
type Scene = *mut c_void;
type Geometry = *mut c_void;

const GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
const GEOMETRY_TYPE_INSTANCE: c_uint = 121;
const FORMAT_FLOAT3X4_ROW_MAJOR: c_uint = 0x9134;
const BUFFER_TYPE_INDEX: c_uint = 0;
const BUFFER_TYPE_VERTEX: c_uint = 1;
const FORMAT_UINT3: c_uint = 0x5003;
const FORMAT_FLOAT3: c_uint = 0x9003;
const BUILD_QUALITY_MEDIUM: c_uint = 1;
const BUILD_QUALITY_HIGH: c_uint = 2;
const SCENE_FLAG_ROBUST: c_uint = 1 << 2;
const INVALID_ID: c_uint = u32::MAX;
const CONTEXT_INCOHERENT: c_uint = 0;
const CONTEXT_COHERENT: c_uint = 1;

/// `RTCRay` (rtcore_ray.h), 48 bytes, 16-byte aligned.
#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct RtcRay {
    org: [f32; 3],
    tnear: f32,
    dir: [f32; 3],
    time: f32,
    tfar: f32,
    mask: c_uint,
    id: c_uint,
    flags: c_uint,
}

/// `RTCHit` with `RTC_MAX_INSTANCE_LEVEL_COUNT = 1`, 32 bytes.
#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct RtcHit {
    ng: [f32; 3],
    u: f32,
    v: f32,
    prim_id: c_uint,
    geom_id: c_uint,
    inst_id: [c_uint; 1],
}

#[repr(C)]
struct RtcRayHit {
    ray: RtcRay,
    hit: RtcHit,
}

/// `RTCRay8`, structure of arrays, 32-byte aligned.
#[repr(C, align(32))]
struct RtcRay8 {
    org_x: [f32; 8],
    org_y: [f32; 8],
    org_z: [f32; 8],
    tnear: [f32; 8],
    dir_x: [f32; 8],
    dir_y: [f32; 8],
    dir_z: [f32; 8],
    time: [f32; 8],
    tfar: [f32; 8],
    mask: [c_uint; 8],
    id: [c_uint; 8],
    flags: [c_uint; 8],
}

#[repr(C, align(32))]
struct RtcHit8 {
    ng_x: [f32; 8],
    ng_y: [f32; 8],
    ng_z: [f32; 8],
    u: [f32; 8],
    v: [f32; 8],
    prim_id: [c_uint; 8],
    geom_id: [c_uint; 8],
    inst_id: [[c_uint; 8]; 1],
}

#[repr(C)]
struct RtcRayHit8 {
    ray: RtcRay8,
    hit: RtcHit8,
}

/// `RTCIntersectContext` with one instance level and no minimum width.
#[repr(C)]
struct RtcContext {
    flags: c_uint,
    filter: *const c_void,
    inst_id: [c_uint; 1],
}

const _: () = assert!(std::mem::size_of::<RtcRay>() == 48 && std::mem::size_of::<RtcHit>() == 32);
const _: () = assert!(std::mem::size_of::<RtcRay8>() == 384 && std::mem::size_of::<RtcHit8>() == 256);

#[link(name = "embree3")]
unsafe extern "C" {
    fn rtcNewDevice(config: *const c_char) -> Device;
    fn rtcReleaseDevice(device: Device);
    fn rtcNewScene(device: Device) -> Scene;
    fn rtcReleaseScene(scene: Scene);
    fn rtcSetSceneBuildQuality(scene: Scene, quality: c_uint);
    fn rtcSetSceneFlags(scene: Scene, flags: c_uint);
    fn rtcNewGeometry(device: Device, kind: c_uint) -> Geometry;
    fn rtcSetGeometryBuildQuality(geometry: Geometry, quality: c_uint);
    fn rtcSetNewGeometryBuffer(
        geometry: Geometry,
        kind: c_uint,
        slot: c_uint,
        format: c_uint,
        byte_stride: usize,
        count: usize,
    ) -> *mut c_void;
    fn rtcCommitGeometry(geometry: Geometry);
    fn rtcAttachGeometry(scene: Scene, geometry: Geometry) -> c_uint;
    fn rtcReleaseGeometry(geometry: Geometry);
    fn rtcCommitScene(scene: Scene);
    fn rtcSetGeometryInstancedScene(geometry: Geometry, scene: Scene);
    fn rtcSetGeometryTransform(geometry: Geometry, time_step: c_uint, format: c_uint, xfm: *const c_void);
    fn rtcIntersect1(scene: Scene, context: *mut RtcContext, rayhit: *mut RtcRayHit);
    fn rtcOccluded1(scene: Scene, context: *mut RtcContext, ray: *mut RtcRay);
    fn rtcIntersect8(valid: *const c_int, scene: Scene, context: *mut RtcContext, rayhit: *mut RtcRayHit8);
    fn rtcOccluded8(valid: *const c_int, scene: Scene, context: *mut RtcContext, ray: *mut RtcRay8);
}

/// One committed Embree scene over a triangle soup.
pub struct Embree {
    device: Device,
    scene: Scene,
    /// The meshes' scenes of a two-level scene (empty otherwise), released after `scene`.
    meshes: Vec<Scene>,
}

// SAFETY: a committed Embree scene may be traced from any thread (Embree's documented contract); it is only
// released in `drop`, which needs exclusive ownership.
unsafe impl Sync for Embree {}

impl Embree {
    /// Builds the scene: HIGH quality, robust traversal when asked, kernels of at most the instruction set
    /// [`max_isa`] names.
    pub fn new(triangles: &[[[f32; 3]; 3]], robust: bool) -> Embree {
        let device = new_device();
        // SAFETY: `device` is a live device; the scene is released once in `drop`.
        let scene = unsafe { triangle_scene(device, triangles, robust) };
        Embree { device, scene, meshes: Vec::new() }
    }

    /// A two-level scene: each of `meshes` in a scene of its own (as [`Embree::new`] builds it), placed by
    /// `instances` (mesh index, 3x4 row-major object-to-world map) as instance geometries of a top scene of the
    /// same quality and flags. Hits report the instance as `instID` (not read here).
    pub fn instanced(meshes: &[Vec<[[f32; 3]; 3]>], instances: &[(u32, [[f32; 4]; 3])], robust: bool) -> Embree {
        let device = new_device();
        // SAFETY: as in `new`; each instance names a mesh scene built here, alive until `drop` (after the top
        // scene, which references them); the transform is 12 floats, read during the call.
        unsafe {
            let mesh_scenes: Vec<Scene> = meshes.iter().map(|m| triangle_scene(device, m, robust)).collect();
            let scene = rtcNewScene(device);
            rtcSetSceneBuildQuality(scene, quality());
            if robust {
                rtcSetSceneFlags(scene, SCENE_FLAG_ROBUST);
            }
            for (mesh, transform) in instances {
                let geometry = rtcNewGeometry(device, GEOMETRY_TYPE_INSTANCE);
                assert!(!geometry.is_null(), "rtcNewGeometry(INSTANCE) failed");
                rtcSetGeometryInstancedScene(geometry, mesh_scenes[*mesh as usize]);
                rtcSetGeometryTransform(geometry, 0, FORMAT_FLOAT3X4_ROW_MAJOR, transform.as_ptr().cast());
                rtcCommitGeometry(geometry);
                rtcAttachGeometry(scene, geometry);
                rtcReleaseGeometry(geometry);
            }
            rtcCommitScene(scene);
            Embree { device, scene, meshes: mesh_scenes }
        }
    }

    fn context(coherent: bool) -> RtcContext {
        RtcContext {
            flags: if coherent { CONTEXT_COHERENT } else { CONTEXT_INCOHERENT },
            filter: std::ptr::null(),
            inst_id: [INVALID_ID],
        }
    }

    fn rtc_ray(ray: &Ray) -> RtcRay {
        RtcRay {
            org: ray.origin,
            tnear: ray.t_min,
            dir: ray.direction,
            time: 0.0,
            tfar: ray.t_max,
            mask: u32::MAX,
            id: 0,
            flags: 0,
        }
    }

    /// Closest hit: `(t, triangle index in the soup)`.
    pub fn closest(&self, ray: &Ray) -> Option<(f32, u32)> {
        let hit =
            RtcHit { ng: [0.0; 3], u: 0.0, v: 0.0, prim_id: INVALID_ID, geom_id: INVALID_ID, inst_id: [INVALID_ID] };
        let mut rayhit = RtcRayHit { ray: Self::rtc_ray(ray), hit };
        let mut context = Self::context(false);
        // SAFETY: the scene is committed; `context` and `rayhit` are valid, aligned and live for the call.
        unsafe { rtcIntersect1(self.scene, &mut context, &mut rayhit) };
        (rayhit.hit.geom_id != INVALID_ID).then_some((rayhit.ray.tfar, rayhit.hit.prim_id))
    }

    /// Any hit.
    pub fn any(&self, ray: &Ray) -> bool {
        let mut rtc = Self::rtc_ray(ray);
        let mut context = Self::context(false);
        // SAFETY: as in `closest`; Embree sets `tfar` to -inf when the ray is occluded.
        unsafe { rtcOccluded1(self.scene, &mut context, &mut rtc) };
        rtc.tfar == f32::NEG_INFINITY
    }

    fn packet(rays: &[Ray]) -> (RtcRay8, [c_int; 8]) {
        let mut packet = RtcRay8 {
            org_x: [0.0; 8],
            org_y: [0.0; 8],
            org_z: [0.0; 8],
            tnear: [0.0; 8],
            dir_x: [0.0; 8],
            dir_y: [0.0; 8],
            dir_z: [1.0; 8],
            time: [0.0; 8],
            tfar: [0.0; 8],
            mask: [u32::MAX; 8],
            id: [0; 8],
            flags: [0; 8],
        };
        let mut valid = [0; 8];
        for (i, r) in rays.iter().take(8).enumerate() {
            (packet.org_x[i], packet.org_y[i], packet.org_z[i]) = (r.origin[0], r.origin[1], r.origin[2]);
            (packet.dir_x[i], packet.dir_y[i], packet.dir_z[i]) = (r.direction[0], r.direction[1], r.direction[2]);
            (packet.tnear[i], packet.tfar[i]) = (r.t_min, r.t_max);
            valid[i] = -1;
        }
        (packet, valid)
    }

    /// Closest hits of up to 8 coherent rays in one packet: how many hit.
    pub fn closest8(&self, rays: &[Ray]) -> usize {
        let (ray, valid) = Self::packet(rays);
        let hit = RtcHit8 {
            ng_x: [0.0; 8],
            ng_y: [0.0; 8],
            ng_z: [0.0; 8],
            u: [0.0; 8],
            v: [0.0; 8],
            prim_id: [INVALID_ID; 8],
            geom_id: [INVALID_ID; 8],
            inst_id: [[INVALID_ID; 8]],
        };
        let mut rayhit = RtcRayHit8 { ray, hit };
        let mut context = Self::context(true);
        // SAFETY: `valid` has 8 lanes, `rayhit` is 32-byte aligned as rtcIntersect8 requires; all live for the call.
        unsafe { rtcIntersect8(valid.as_ptr(), self.scene, &mut context, &mut rayhit) };
        (0..rays.len().min(8)).filter(|&i| rayhit.hit.geom_id[i] != INVALID_ID).count()
    }

    /// Any hit of up to 8 rays in one packet: how many are occluded.
    pub fn any8(&self, rays: &[Ray]) -> usize {
        let (mut ray, valid) = Self::packet(rays);
        let mut context = Self::context(true);
        // SAFETY: as in `closest8`.
        unsafe { rtcOccluded8(valid.as_ptr(), self.scene, &mut context, &mut ray) };
        (0..rays.len().min(8)).filter(|&i| ray.tfar[i] == f32::NEG_INFINITY).count()
    }
}

impl Drop for Embree {
    fn drop(&mut self) {
        // SAFETY: every handle came from Embree in `new` or `instanced` and is released exactly once, the top
        // scene before the mesh scenes it instances, the device last.
        unsafe {
            rtcReleaseScene(self.scene);
            for &mesh in &self.meshes {
                rtcReleaseScene(mesh);
            }
            rtcReleaseDevice(self.device);
        }
    }
}

/// A device with one thread and at most [`max_isa`]'s kernels.
fn new_device() -> Device {
    let config = std::ffi::CString::new(format!("threads=1,max_isa={}", max_isa())).expect("no NUL");
    // SAFETY: the config string is NUL-terminated and lives for the call.
    let device = unsafe { rtcNewDevice(config.as_ptr()) };
    assert!(!device.is_null(), "rtcNewDevice failed");
    device
}

/// A committed scene of one triangle geometry over `triangles`, HIGH quality (or `BVHC_EMBREE_QUALITY`), robust
/// when asked.
///
/// # Safety
///
/// `device` must be a live Embree device; the caller releases the scene.
unsafe fn triangle_scene(device: Device, triangles: &[[[f32; 3]; 3]], robust: bool) -> Scene {
    // SAFETY: the buffers Embree returns are sized by the counts passed (plus Embree's own padding) and written
    // within them; handles are checked for null before use.
    unsafe {
        let scene = rtcNewScene(device);
        rtcSetSceneBuildQuality(scene, quality());
        if robust {
            rtcSetSceneFlags(scene, SCENE_FLAG_ROBUST);
        }
        let geometry = rtcNewGeometry(device, GEOMETRY_TYPE_TRIANGLE);
        rtcSetGeometryBuildQuality(geometry, quality());
        let n = triangles.len();
        let vertices = rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_VERTEX, 0, FORMAT_FLOAT3, 12, 3 * n) as *mut f32;
        let indices = rtcSetNewGeometryBuffer(geometry, BUFFER_TYPE_INDEX, 0, FORMAT_UINT3, 12, n) as *mut u32;
        assert!(!vertices.is_null() && !indices.is_null(), "rtcSetNewGeometryBuffer failed");
        let vertices = std::slice::from_raw_parts_mut(vertices, 9 * n);
        let indices = std::slice::from_raw_parts_mut(indices, 3 * n);
        for (t, triangle) in triangles.iter().enumerate() {
            for (k, v) in triangle.iter().enumerate() {
                vertices[9 * t + 3 * k..9 * t + 3 * k + 3].copy_from_slice(v);
                indices[3 * t + k] = (3 * t + k) as u32;
            }
        }
        rtcCommitGeometry(geometry);
        rtcAttachGeometry(scene, geometry);
        rtcReleaseGeometry(geometry);
        rtcCommitScene(scene);
        scene
    }
}

/// Sets flush-to-zero and denormals-are-zero on this thread (MXCSR bits 15 and 6), as Embree recommends.
pub fn set_flush_to_zero() {
    #[cfg(target_arch = "x86_64")]
    {
        let mut csr: u32 = 0;
        // SAFETY: stmxcsr/ldmxcsr only read and write the MXCSR register of this thread; setting FTZ and DAZ
        // changes how denormals round in this benchmark thread, nothing else.
        unsafe {
            std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack));
            csr |= (1 << 15) | (1 << 6);
            std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack));
        }
    }
}

/// The build quality: `BVHC_EMBREE_QUALITY=medium` (binned SAH, no spatial splits), else HIGH (spatial
/// splits), the quality the targets name.
pub fn quality() -> c_uint {
    match std::env::var("BVHC_EMBREE_QUALITY").as_deref() {
        Ok("medium") => BUILD_QUALITY_MEDIUM,
        _ => BUILD_QUALITY_HIGH,
    }
}

/// The most capable instruction set Embree may use: `BVHC_EMBREE_ISA` (`sse2`, `sse4.2`, `avx`, `avx2` or
/// `avx512`), `avx2` by default, the instruction set of bvhc's SIMD kernel (on a machine with AVX-512, Embree
/// would otherwise pick its AVX-512 kernels; `avx512` lets it).
pub fn max_isa() -> String {
    std::env::var("BVHC_EMBREE_ISA").unwrap_or_else(|_| "avx2".to_string())
}
