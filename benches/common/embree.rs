//! Embree as a benchmark peer, through a small FFI of our own: Embree 3 (Debian's `libembree3` 3.13.5,
//! `apt-get install libembree-dev`) with `--features embree`, or Embree 4.4 (the library of the `embreex` wheel,
//! prepared by `scripts/embree4.sh`) with `--features embree4`. Never compiled by the default build, the tests or
//! CI. The two versions share the scene setup; they differ in the library's name, the hit record (4.4's wheel is
//! built with instance arrays, which add `instPrimID`), and the query calls (Embree 3 takes an intersection
//! context before the ray, Embree 4 optional arguments after it), which [`api`] hides.
//!
//! One triangle mesh per scene, built with `RTC_BUILD_QUALITY_HIGH` (spatial splits), optionally with
//! `RTC_SCENE_FLAG_ROBUST`, or meshes placed by instance geometries (`RTC_GEOMETRY_TYPE_INSTANCE`, a 3x4
//! row-major transform each, Embree's two-level scenes); single rays through `rtcIntersect1` / `rtcOccluded1`
//! and 8- and 16-wide packets through `rtcIntersect8/16` / `rtcOccluded8/16`. The calling thread needs
//! flush-to-zero and denormals-are-zero, as Embree asks ([`FlushToZero`]).
#![allow(unsafe_code)] // FFI: every call's contract is stated beside it.
#![allow(dead_code)] // each benchmark uses the part it needs

#[cfg(all(feature = "embree", feature = "embree4"))]
compile_error!("the features `embree` (Embree 3) and `embree4` link libraries with the same symbols: pick one");

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

/// The Embree version these benchmarks link, for their tables.
pub const VERSION: &str = if cfg!(feature = "embree4") { "Embree 4.4.0" } else { "Embree 3.13.5" };

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

/// `RTCHit` with `RTC_MAX_INSTANCE_LEVEL_COUNT = 1` (and, in Embree 4.4 with instance arrays, `instPrimID`):
/// 32 or 48 bytes.
#[repr(C, align(16))]
#[derive(Clone, Copy)]
struct RtcHit {
    ng: [f32; 3],
    u: f32,
    v: f32,
    prim_id: c_uint,
    geom_id: c_uint,
    inst_id: [c_uint; 1],
    #[cfg(feature = "embree4")]
    inst_prim_id: [c_uint; 1],
}

impl RtcHit {
    const EMPTY: RtcHit = RtcHit {
        ng: [0.0; 3],
        u: 0.0,
        v: 0.0,
        prim_id: INVALID_ID,
        geom_id: INVALID_ID,
        inst_id: [INVALID_ID],
        #[cfg(feature = "embree4")]
        inst_prim_id: [INVALID_ID],
    };
}

#[repr(C)]
struct RtcRayHit {
    ray: RtcRay,
    hit: RtcHit,
}

/// `RTCRayN` for N = 8 or 16, structure of arrays.
#[repr(C)]
#[derive(Clone, Copy)]
struct RtcRayN<const N: usize> {
    org_x: [f32; N],
    org_y: [f32; N],
    org_z: [f32; N],
    tnear: [f32; N],
    dir_x: [f32; N],
    dir_y: [f32; N],
    dir_z: [f32; N],
    time: [f32; N],
    tfar: [f32; N],
    mask: [c_uint; N],
    id: [c_uint; N],
    flags: [c_uint; N],
}

/// `RTCHitN` for N = 8 or 16.
#[repr(C)]
#[derive(Clone, Copy)]
struct RtcHitN<const N: usize> {
    ng_x: [f32; N],
    ng_y: [f32; N],
    ng_z: [f32; N],
    u: [f32; N],
    v: [f32; N],
    prim_id: [c_uint; N],
    geom_id: [c_uint; N],
    inst_id: [[c_uint; N]; 1],
    #[cfg(feature = "embree4")]
    inst_prim_id: [[c_uint; N]; 1],
}

/// `RTCRayHitN`, aligned as Embree asks of 8-packets (32) and 16-packets (64): 64 serves both.
#[repr(C, align(64))]
struct RtcRayHitN<const N: usize> {
    ray: RtcRayN<N>,
    hit: RtcHitN<N>,
}

/// A ray packet alone (for occlusion), 64-byte aligned.
#[repr(C, align(64))]
struct RtcRayPacket<const N: usize>(RtcRayN<N>);

#[cfg(not(feature = "embree4"))]
const _: () = assert!(size_of::<RtcRay>() == 48 && size_of::<RtcHit>() == 32 && size_of::<RtcHitN<8>>() == 256);
#[cfg(feature = "embree4")]
const _: () = assert!(size_of::<RtcRay>() == 48 && size_of::<RtcHit>() == 48 && size_of::<RtcHitN<8>>() == 288);

#[cfg_attr(not(feature = "embree4"), link(name = "embree3"))]
#[cfg_attr(feature = "embree4", link(name = "embree4"))]
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
}

/// The query calls of Embree 3: an `RTCIntersectContext` (flags, filter, instance stack) before the ray.
#[cfg(not(feature = "embree4"))]
mod api {
    use super::*;

    #[repr(C)]
    struct Context {
        flags: c_uint,
        filter: *const c_void,
        inst_id: [c_uint; 1],
    }

    impl Context {
        fn new(coherent: bool) -> Context {
            Context { flags: u32::from(coherent), filter: std::ptr::null(), inst_id: [INVALID_ID] }
        }
    }

    #[link(name = "embree3")]
    unsafe extern "C" {
        fn rtcIntersect1(scene: Scene, context: *mut Context, rayhit: *mut RtcRayHit);
        fn rtcOccluded1(scene: Scene, context: *mut Context, ray: *mut RtcRay);
        fn rtcIntersect8(valid: *const c_int, scene: Scene, context: *mut Context, rayhit: *mut RtcRayHitN<8>);
        fn rtcOccluded8(valid: *const c_int, scene: Scene, context: *mut Context, ray: *mut RtcRayPacket<8>);
        fn rtcIntersect16(valid: *const c_int, scene: Scene, context: *mut Context, rayhit: *mut RtcRayHitN<16>);
        fn rtcOccluded16(valid: *const c_int, scene: Scene, context: *mut Context, ray: *mut RtcRayPacket<16>);
    }

    /// # Safety
    /// `scene` must be a committed scene; the pointers valid and aligned for the call.
    pub(super) unsafe fn intersect1(scene: Scene, rayhit: *mut RtcRayHit) {
        // SAFETY: the caller's contract; the context lives for the call.
        unsafe { rtcIntersect1(scene, &mut Context::new(false), rayhit) }
    }
    /// # Safety
    /// As [`intersect1`].
    pub(super) unsafe fn occluded1(scene: Scene, ray: *mut RtcRay) {
        // SAFETY: as above.
        unsafe { rtcOccluded1(scene, &mut Context::new(false), ray) }
    }
    /// # Safety
    /// As [`intersect1`], `valid` holding 8 lanes.
    pub(super) unsafe fn intersect8(valid: *const c_int, scene: Scene, rayhit: *mut RtcRayHitN<8>) {
        // SAFETY: as above.
        unsafe { rtcIntersect8(valid, scene, &mut Context::new(true), rayhit) }
    }
    /// # Safety
    /// As [`intersect8`].
    pub(super) unsafe fn occluded8(valid: *const c_int, scene: Scene, ray: *mut RtcRayPacket<8>) {
        // SAFETY: as above.
        unsafe { rtcOccluded8(valid, scene, &mut Context::new(true), ray) }
    }
    /// # Safety
    /// As [`intersect1`], `valid` holding 16 lanes.
    pub(super) unsafe fn intersect16(valid: *const c_int, scene: Scene, rayhit: *mut RtcRayHitN<16>) {
        // SAFETY: as above.
        unsafe { rtcIntersect16(valid, scene, &mut Context::new(true), rayhit) }
    }
    /// # Safety
    /// As [`intersect16`].
    pub(super) unsafe fn occluded16(valid: *const c_int, scene: Scene, ray: *mut RtcRayPacket<16>) {
        // SAFETY: as above.
        unsafe { rtcOccluded16(valid, scene, &mut Context::new(true), ray) }
    }
    /// The device configuration that caps the kernels at `isa`.
    pub(super) fn isa_config(isa: &str) -> String {
        format!("max_isa={isa}")
    }
}

/// The query calls of Embree 4: optional `RTCIntersectArguments` / `RTCOccludedArguments` after the ray (NULL
/// for single rays: incoherent, every feature; the coherent flag for packets).
#[cfg(feature = "embree4")]
mod api {
    use super::*;

    /// Both argument structs share this layout up to their callback (intersect or occluded); the trailing float
    /// is `minWidthDistanceFactor` of builds with `RTC_MIN_WIDTH`, zero (ignored by builds without it).
    #[repr(C)]
    struct Arguments {
        flags: c_uint,
        feature_mask: c_uint,
        context: *mut c_void,
        filter: *const c_void,
        callback: *const c_void,
        min_width_distance_factor: f32,
    }

    const RAY_QUERY_FLAG_COHERENT: c_uint = 1 << 16;
    const FEATURE_FLAG_ALL: c_uint = 0xffff_ffff;

    fn coherent() -> Arguments {
        Arguments {
            flags: RAY_QUERY_FLAG_COHERENT,
            feature_mask: FEATURE_FLAG_ALL,
            context: std::ptr::null_mut(),
            filter: std::ptr::null(),
            callback: std::ptr::null(),
            min_width_distance_factor: 0.0,
        }
    }

    #[link(name = "embree4")]
    unsafe extern "C" {
        fn rtcIntersect1(scene: Scene, rayhit: *mut RtcRayHit, args: *mut Arguments);
        fn rtcOccluded1(scene: Scene, ray: *mut RtcRay, args: *mut Arguments);
        fn rtcIntersect8(valid: *const c_int, scene: Scene, rayhit: *mut RtcRayHitN<8>, args: *mut Arguments);
        fn rtcOccluded8(valid: *const c_int, scene: Scene, ray: *mut RtcRayPacket<8>, args: *mut Arguments);
        fn rtcIntersect16(valid: *const c_int, scene: Scene, rayhit: *mut RtcRayHitN<16>, args: *mut Arguments);
        fn rtcOccluded16(valid: *const c_int, scene: Scene, ray: *mut RtcRayPacket<16>, args: *mut Arguments);
    }

    /// # Safety
    /// `scene` must be a committed scene; the pointers valid and aligned for the call.
    pub(super) unsafe fn intersect1(scene: Scene, rayhit: *mut RtcRayHit) {
        // SAFETY: the caller's contract; NULL arguments are Embree's defaults.
        unsafe { rtcIntersect1(scene, rayhit, std::ptr::null_mut()) }
    }
    /// # Safety
    /// As [`intersect1`].
    pub(super) unsafe fn occluded1(scene: Scene, ray: *mut RtcRay) {
        // SAFETY: as above.
        unsafe { rtcOccluded1(scene, ray, std::ptr::null_mut()) }
    }
    /// # Safety
    /// As [`intersect1`], `valid` holding 8 lanes.
    pub(super) unsafe fn intersect8(valid: *const c_int, scene: Scene, rayhit: *mut RtcRayHitN<8>) {
        // SAFETY: as above; the arguments live for the call.
        unsafe { rtcIntersect8(valid, scene, rayhit, &mut coherent()) }
    }
    /// # Safety
    /// As [`intersect8`].
    pub(super) unsafe fn occluded8(valid: *const c_int, scene: Scene, ray: *mut RtcRayPacket<8>) {
        // SAFETY: as above.
        unsafe { rtcOccluded8(valid, scene, ray, &mut coherent()) }
    }
    /// # Safety
    /// As [`intersect1`], `valid` holding 16 lanes.
    pub(super) unsafe fn intersect16(valid: *const c_int, scene: Scene, rayhit: *mut RtcRayHitN<16>) {
        // SAFETY: as above.
        unsafe { rtcIntersect16(valid, scene, rayhit, &mut coherent()) }
    }
    /// # Safety
    /// As [`intersect16`].
    pub(super) unsafe fn occluded16(valid: *const c_int, scene: Scene, ray: *mut RtcRayPacket<16>) {
        // SAFETY: as above.
        unsafe { rtcOccluded16(valid, scene, ray, &mut coherent()) }
    }
    /// The device configuration that pins the kernels to `isa`.
    pub(super) fn isa_config(isa: &str) -> String {
        format!("isa={isa}")
    }
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
        Embree::with_isa(triangles, robust, Some(&max_isa()))
    }

    /// [`Embree::new`] on the kernels of `isa` (`None`: Embree's choice for this CPU, its native one).
    pub fn with_isa(triangles: &[[[f32; 3]; 3]], robust: bool, isa: Option<&str>) -> Embree {
        let device = new_device(isa);
        // SAFETY: `device` is a live device; the scene is released once in `drop`.
        let scene = unsafe { triangle_scene(device, triangles, robust) };
        Embree { device, scene, meshes: Vec::new() }
    }

    /// A two-level scene: each of `meshes` in a scene of its own (as [`Embree::new`] builds it), placed by
    /// `instances` (mesh index, 3x4 row-major object-to-world map) as instance geometries of a top scene of the
    /// same quality and flags. Hits report the instance as `instID` (not read here).
    pub fn instanced(meshes: &[Vec<[[f32; 3]; 3]>], instances: &[(u32, [[f32; 4]; 3])], robust: bool) -> Embree {
        let device = new_device(Some(&max_isa()));
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
        let mut rayhit = RtcRayHit { ray: Self::rtc_ray(ray), hit: RtcHit::EMPTY };
        // SAFETY: the scene is committed; `rayhit` is valid, aligned and live for the call.
        unsafe { api::intersect1(self.scene, &mut rayhit) };
        (rayhit.hit.geom_id != INVALID_ID).then_some((rayhit.ray.tfar, rayhit.hit.prim_id))
    }

    /// Any hit.
    pub fn any(&self, ray: &Ray) -> bool {
        let mut rtc = Self::rtc_ray(ray);
        // SAFETY: as in `closest`; Embree sets `tfar` to -inf when the ray is occluded.
        unsafe { api::occluded1(self.scene, &mut rtc) };
        rtc.tfar == f32::NEG_INFINITY
    }

    fn packet<const N: usize>(rays: &[Ray]) -> (RtcRayN<N>, [c_int; N]) {
        let mut packet = RtcRayN {
            org_x: [0.0; N],
            org_y: [0.0; N],
            org_z: [0.0; N],
            tnear: [0.0; N],
            dir_x: [0.0; N],
            dir_y: [0.0; N],
            dir_z: [1.0; N],
            time: [0.0; N],
            tfar: [0.0; N],
            mask: [u32::MAX; N],
            id: [0; N],
            flags: [0; N],
        };
        let mut valid = [0; N];
        for (i, r) in rays.iter().take(N).enumerate() {
            (packet.org_x[i], packet.org_y[i], packet.org_z[i]) = (r.origin[0], r.origin[1], r.origin[2]);
            (packet.dir_x[i], packet.dir_y[i], packet.dir_z[i]) = (r.direction[0], r.direction[1], r.direction[2]);
            (packet.tnear[i], packet.tfar[i]) = (r.t_min, r.t_max);
            valid[i] = -1;
        }
        (packet, valid)
    }

    fn empty_hits<const N: usize>() -> RtcHitN<N> {
        RtcHitN {
            ng_x: [0.0; N],
            ng_y: [0.0; N],
            ng_z: [0.0; N],
            u: [0.0; N],
            v: [0.0; N],
            prim_id: [INVALID_ID; N],
            geom_id: [INVALID_ID; N],
            inst_id: [[INVALID_ID; N]],
            #[cfg(feature = "embree4")]
            inst_prim_id: [[INVALID_ID; N]],
        }
    }

    /// Closest hits of up to 8 coherent rays in one packet, into `out` (`t` of a hit, `None` of a miss).
    pub fn closest8_into(&self, rays: &[Ray], out: &mut [Option<f32>]) {
        let (ray, valid) = Self::packet::<8>(rays);
        let mut rayhit = RtcRayHitN { ray, hit: Self::empty_hits() };
        // SAFETY: `valid` has 8 lanes, `rayhit` is 64-byte aligned (Embree asks 32); all live for the call.
        unsafe { api::intersect8(valid.as_ptr(), self.scene, &mut rayhit) };
        for (i, slot) in out.iter_mut().enumerate().take(rays.len().min(8)) {
            *slot = (rayhit.hit.geom_id[i] != INVALID_ID).then_some(rayhit.ray.tfar[i]);
        }
    }

    /// Closest hits of up to 16 coherent rays in one packet, into `out`.
    pub fn closest16_into(&self, rays: &[Ray], out: &mut [Option<f32>]) {
        let (ray, valid) = Self::packet::<16>(rays);
        let mut rayhit = RtcRayHitN { ray, hit: Self::empty_hits() };
        // SAFETY: `valid` has 16 lanes, `rayhit` is 64-byte aligned as Embree asks; all live for the call.
        unsafe { api::intersect16(valid.as_ptr(), self.scene, &mut rayhit) };
        for (i, slot) in out.iter_mut().enumerate().take(rays.len().min(16)) {
            *slot = (rayhit.hit.geom_id[i] != INVALID_ID).then_some(rayhit.ray.tfar[i]);
        }
    }

    /// Closest hits of up to 8 coherent rays in one packet: how many hit.
    pub fn closest8(&self, rays: &[Ray]) -> usize {
        let mut out = [None; 8];
        self.closest8_into(rays, &mut out);
        out.iter().take(rays.len()).filter(|t| t.is_some()).count()
    }

    /// Any hit of up to 8 rays in one packet: how many are occluded.
    pub fn any8(&self, rays: &[Ray]) -> usize {
        let (ray, valid) = Self::packet::<8>(rays);
        let mut packet = RtcRayPacket(ray);
        // SAFETY: as in `closest8_into`.
        unsafe { api::occluded8(valid.as_ptr(), self.scene, &mut packet) };
        (0..rays.len().min(8)).filter(|&i| packet.0.tfar[i] == f32::NEG_INFINITY).count()
    }

    /// Any hit of up to 16 rays in one packet: how many are occluded.
    pub fn any16(&self, rays: &[Ray]) -> usize {
        let (ray, valid) = Self::packet::<16>(rays);
        let mut packet = RtcRayPacket(ray);
        // SAFETY: as in `closest16_into`.
        unsafe { api::occluded16(valid.as_ptr(), self.scene, &mut packet) };
        (0..rays.len().min(16)).filter(|&i| packet.0.tfar[i] == f32::NEG_INFINITY).count()
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

/// A device with one thread and the kernels of `isa` at most (`None`: Embree's native choice).
fn new_device(isa: Option<&str>) -> Device {
    let config = match isa {
        Some(isa) => format!("threads=1,{}", api::isa_config(isa)),
        None => "threads=1".to_string(),
    };
    let config = std::ffi::CString::new(config).expect("no NUL");
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

/// Flush-to-zero and denormals-are-zero (MXCSR bits 15 and 6) on this thread while the value lives, as Embree
/// asks; the previous mode comes back when it is dropped (bvhc's kernels need IEEE subnormals).
pub struct FlushToZero {
    saved: u32,
}

impl FlushToZero {
    pub fn set() -> FlushToZero {
        let saved = read_mxcsr();
        write_mxcsr(saved | (1 << 15) | (1 << 6));
        FlushToZero { saved }
    }
}

impl Drop for FlushToZero {
    fn drop(&mut self) {
        write_mxcsr(self.saved);
    }
}

fn read_mxcsr() -> u32 {
    let mut csr: u32 = 0;
    // SAFETY: stmxcsr only stores this thread's MXCSR register into `csr`.
    #[cfg(target_arch = "x86_64")]
    unsafe {
        std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack));
    }
    csr
}

fn write_mxcsr(csr: u32) {
    // SAFETY: ldmxcsr only sets this thread's floating-point mode (rounding, FTZ, DAZ, exception masks) from a
    // value read from it, with at most FTZ and DAZ added.
    #[cfg(target_arch = "x86_64")]
    unsafe {
        std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack));
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = csr;
}

/// Sets flush-to-zero and denormals-are-zero on this thread for good (a thread that only runs Embree).
pub fn set_flush_to_zero() {
    std::mem::forget(FlushToZero::set());
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

#[path = "embree_deformable.rs"]
pub mod deformable;
