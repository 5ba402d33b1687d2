//! Embree 3 back-end through relight's own minimal FFI (no `embree` crate, no build script).
//!
//! Links `libembree3` (Debian `libembree-dev`, 3.13.5; headers in `/usr/include/embree3`).
//! The `#[repr(C)]` structs below mirror `rtcore_ray.h` / `rtcore_common.h` of that release
//! (`RTC_MAX_INSTANCE_LEVEL_COUNT = 1`, `RTC_MIN_WIDTH = 0`); their sizes and alignments are
//! checked at compile time. `rtcInitIntersectContext` is a `static inline` in the header, so
//! `init_context` re-implements it.
//!
//! Thread safety: after `rtcCommitScene`, Embree allows concurrent `rtcIntersect*` /
//! `rtcOccluded*` calls on one scene from any number of threads (Embree 3 API docs,
//! "rtcCommitScene"), which is why [`EmbreeScene`] is `Send + Sync`.

use super::{AccelError, Hit, Ray, RayCaster};
use crate::mesh::TriMesh;
use std::ffi::{c_char, c_void, CStr};
use std::sync::Mutex;

/// Raw bindings: only the handful of entry points relight uses.
#[allow(non_camel_case_types, missing_docs)]
mod sys {
    use std::ffi::{c_char, c_uint, c_void};

    pub type RTCDevice = *mut c_void;
    pub type RTCScene = *mut c_void;
    pub type RTCGeometry = *mut c_void;
    pub type RTCErrorFunction = extern "C" fn(user: *mut c_void, code: c_uint, msg: *const c_char);

    pub const RTC_GEOMETRY_TYPE_TRIANGLE: c_uint = 0;
    pub const RTC_BUFFER_TYPE_INDEX: c_uint = 0;
    pub const RTC_BUFFER_TYPE_VERTEX: c_uint = 1;
    pub const RTC_FORMAT_UINT3: c_uint = 0x5003;
    pub const RTC_FORMAT_FLOAT3: c_uint = 0x9003;
    pub const RTC_BUILD_QUALITY_HIGH: c_uint = 2;
    pub const RTC_SCENE_FLAG_ROBUST: c_uint = 1 << 2;
    pub const RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT: c_uint = 0;
    pub const RTC_INVALID_GEOMETRY_ID: c_uint = u32::MAX;

    /// `struct RTC_ALIGN(16) RTCRay` (rtcore_ray.h).
    #[repr(C, align(16))]
    #[derive(Clone, Copy, Debug)]
    pub struct RTCRay {
        pub org_x: f32,
        pub org_y: f32,
        pub org_z: f32,
        pub tnear: f32,
        pub dir_x: f32,
        pub dir_y: f32,
        pub dir_z: f32,
        pub time: f32,
        pub tfar: f32,
        pub mask: c_uint,
        pub id: c_uint,
        pub flags: c_uint,
    }

    /// `struct RTC_ALIGN(16) RTCHit` (rtcore_ray.h) with one instance level.
    #[repr(C, align(16))]
    #[derive(Clone, Copy, Debug)]
    pub struct RTCHit {
        pub ng_x: f32,
        pub ng_y: f32,
        pub ng_z: f32,
        pub u: f32,
        pub v: f32,
        pub prim_id: c_uint,
        pub geom_id: c_uint,
        pub inst_id: [c_uint; 1],
    }

    /// `struct RTCRayHit` (rtcore_ray.h).
    #[repr(C)]
    #[derive(Clone, Copy, Debug)]
    pub struct RTCRayHit {
        pub ray: RTCRay,
        pub hit: RTCHit,
    }

    /// `struct RTCIntersectContext` (rtcore_common.h): flags, filter, instID[1].
    #[repr(C)]
    pub struct RTCIntersectContext {
        pub flags: c_uint,
        pub filter: *const c_void,
        pub inst_id: [c_uint; 1],
    }

    // Layout checks against the 3.13.5 header.
    const _: () = assert!(size_of::<RTCRay>() == 48 && align_of::<RTCRay>() == 16);
    const _: () = assert!(size_of::<RTCHit>() == 32 && align_of::<RTCHit>() == 16);
    const _: () = assert!(size_of::<RTCRayHit>() == 80 && align_of::<RTCRayHit>() == 16);
    const _: () = assert!(std::mem::offset_of!(RTCRay, tfar) == 32);
    const _: () = assert!(std::mem::offset_of!(RTCHit, prim_id) == 20);
    const _: () = assert!(size_of::<RTCIntersectContext>() == 24);
    const _: () = assert!(std::mem::offset_of!(RTCIntersectContext, inst_id) == 16);

    #[link(name = "embree3")]
    extern "C" {
        pub fn rtcNewDevice(config: *const c_char) -> RTCDevice;
        pub fn rtcReleaseDevice(device: RTCDevice);
        pub fn rtcGetDeviceError(device: RTCDevice) -> c_uint;
        pub fn rtcSetDeviceErrorFunction(device: RTCDevice, f: RTCErrorFunction, user: *mut c_void);
        pub fn rtcNewScene(device: RTCDevice) -> RTCScene;
        pub fn rtcReleaseScene(scene: RTCScene);
        pub fn rtcSetSceneBuildQuality(scene: RTCScene, quality: c_uint);
        pub fn rtcSetSceneFlags(scene: RTCScene, flags: c_uint);
        pub fn rtcCommitScene(scene: RTCScene);
        pub fn rtcNewGeometry(device: RTCDevice, kind: c_uint) -> RTCGeometry;
        pub fn rtcSetNewGeometryBuffer(
            geometry: RTCGeometry,
            kind: c_uint,
            slot: c_uint,
            format: c_uint,
            byte_stride: usize,
            item_count: usize,
        ) -> *mut c_void;
        pub fn rtcCommitGeometry(geometry: RTCGeometry);
        pub fn rtcAttachGeometry(scene: RTCScene, geometry: RTCGeometry) -> c_uint;
        pub fn rtcReleaseGeometry(geometry: RTCGeometry);
        pub fn rtcIntersect1(
            scene: RTCScene,
            ctx: *mut RTCIntersectContext,
            rayhit: *mut RTCRayHit,
        );
        pub fn rtcOccluded1(scene: RTCScene, ctx: *mut RTCIntersectContext, ray: *mut RTCRay);
        pub fn rtcIntersect1M(
            scene: RTCScene,
            ctx: *mut RTCIntersectContext,
            rayhit: *mut RTCRayHit,
            m: c_uint,
            byte_stride: usize,
        );
        pub fn rtcOccluded1M(
            scene: RTCScene,
            ctx: *mut RTCIntersectContext,
            ray: *mut RTCRay,
            m: c_uint,
            byte_stride: usize,
        );
    }
}

/// `rtcInitIntersectContext` of rtcore_common.h (a `static inline`, so not in the library):
/// incoherent rays, no filter, empty instance stack.
fn init_context() -> sys::RTCIntersectContext {
    sys::RTCIntersectContext {
        flags: sys::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT,
        filter: std::ptr::null(),
        inst_id: [sys::RTC_INVALID_GEOMETRY_ID],
    }
}

/// Embree's error callback: keeps the first message for [`EmbreeScene::build`] to report.
extern "C" fn on_error(user: *mut c_void, code: u32, msg: *const c_char) {
    // SAFETY: `user` is the `Mutex<Option<String>>` boxed in `Device`, alive while the device
    // is; Embree passes a NUL-terminated message or null.
    let slot = unsafe { &*(user as *const Mutex<Option<String>>) };
    let text = if msg.is_null() {
        String::new()
    } else {
        unsafe { CStr::from_ptr(msg) }
            .to_string_lossy()
            .into_owned()
    };
    if let Ok(mut s) = slot.lock() {
        s.get_or_insert_with(|| format!("error {code}: {text}"));
    }
}

/// An Embree device with its error slot; released on drop.
struct Device {
    raw: sys::RTCDevice,
    // Boxed so its address, handed to Embree as the callback's user pointer, is stable.
    error: Box<Mutex<Option<String>>>,
}

impl Device {
    fn new() -> Result<Self, AccelError> {
        // SAFETY: a null config string selects Embree's defaults.
        let raw = unsafe { sys::rtcNewDevice(std::ptr::null()) };
        if raw.is_null() {
            return Err(AccelError::Embree {
                call: "rtcNewDevice",
                message: "failed (unsupported CPU or library missing)".into(),
            });
        }
        let error = Box::new(Mutex::new(None));
        let user = &*error as *const Mutex<Option<String>> as *mut c_void;
        // SAFETY: `raw` is a live device; `user` outlives it (dropped after rtcReleaseDevice).
        unsafe { sys::rtcSetDeviceErrorFunction(raw, on_error, user) };
        Ok(Device { raw, error })
    }

    /// `Err` with the callback's message (or the bare code) if Embree reported an error.
    fn check(&self, call: &'static str) -> Result<(), AccelError> {
        // SAFETY: live device.
        let code = unsafe { sys::rtcGetDeviceError(self.raw) };
        let msg = self.error.lock().ok().and_then(|mut s| s.take());
        match (code, msg) {
            (0, None) => Ok(()),
            (_, Some(message)) => Err(AccelError::Embree { call, message }),
            (c, None) => Err(AccelError::Embree {
                call,
                message: format!("error code {c}"),
            }),
        }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: the device is live and released exactly once, after its scene.
        unsafe { sys::rtcReleaseDevice(self.raw) };
    }
}

/// A committed Embree scene holding one triangle mesh (geometry id 0). Triangle ids in hits
/// are the mesh's triangle indices.
pub struct EmbreeScene {
    scene: sys::RTCScene,
    robust: bool,
    // Dropped after `scene` (see `Drop`), keeping the error slot alive.
    device: Device,
}

// SAFETY: a committed Embree scene is immutable and Embree documents concurrent queries on it
// as thread-safe; the handles are only released in `Drop`, which takes `&mut self`.
unsafe impl Send for EmbreeScene {}
unsafe impl Sync for EmbreeScene {}

impl EmbreeScene {
    /// Copy `mesh` into a new Embree scene (build quality high, default scene flags: Embree's
    /// fast mode, which is not watertight, see `embree_robust_is_watertight`) and commit it.
    ///
    /// # Errors
    /// Mesh without usable triangles, out-of-range indices, or any Embree device error.
    pub fn build(mesh: &TriMesh) -> Result<Self, AccelError> {
        super::bvh::check_mesh(mesh)?;
        Self::build_with_flags(mesh, 0)
    }

    /// As [`EmbreeScene::build`] with `RTC_SCENE_FLAG_ROBUST`: watertight (no ray slips
    /// through a shared edge or vertex), somewhat slower.
    ///
    /// # Errors
    /// As [`EmbreeScene::build`].
    pub fn build_robust(mesh: &TriMesh) -> Result<Self, AccelError> {
        super::bvh::check_mesh(mesh)?;
        Self::build_with_flags(mesh, sys::RTC_SCENE_FLAG_ROBUST)
    }

    fn build_with_flags(mesh: &TriMesh, flags: u32) -> Result<Self, AccelError> {
        let device = Device::new()?;
        // SAFETY: every handle below comes from `device` and is checked for null; buffers
        // returned by rtcSetNewGeometryBuffer hold `count * stride` bytes (plus Embree's own
        // padding), and we write exactly `count` items into each.
        unsafe {
            let scene = sys::rtcNewScene(device.raw);
            if scene.is_null() {
                device.check("rtcNewScene")?;
                return Err(AccelError::Embree {
                    call: "rtcNewScene",
                    message: "returned null".into(),
                });
            }
            // From here on the scene is owned by `this`, so early returns release it.
            let robust = flags & sys::RTC_SCENE_FLAG_ROBUST != 0;
            let this = EmbreeScene {
                scene,
                robust,
                device,
            };
            sys::rtcSetSceneBuildQuality(scene, sys::RTC_BUILD_QUALITY_HIGH);
            sys::rtcSetSceneFlags(scene, flags);
            let geom = sys::rtcNewGeometry(this.device.raw, sys::RTC_GEOMETRY_TYPE_TRIANGLE);
            if geom.is_null() {
                this.device.check("rtcNewGeometry")?;
                return Err(AccelError::Embree {
                    call: "rtcNewGeometry",
                    message: "returned null".into(),
                });
            }
            let nv = mesh.positions.len();
            let nt = mesh.indices.len();
            let vb = sys::rtcSetNewGeometryBuffer(
                geom,
                sys::RTC_BUFFER_TYPE_VERTEX,
                0,
                sys::RTC_FORMAT_FLOAT3,
                12,
                nv,
            ) as *mut [f32; 3];
            let ib = sys::rtcSetNewGeometryBuffer(
                geom,
                sys::RTC_BUFFER_TYPE_INDEX,
                0,
                sys::RTC_FORMAT_UINT3,
                12,
                nt,
            ) as *mut [u32; 3];
            if vb.is_null() || ib.is_null() {
                sys::rtcReleaseGeometry(geom);
                this.device.check("rtcSetNewGeometryBuffer")?;
                return Err(AccelError::Embree {
                    call: "rtcSetNewGeometryBuffer",
                    message: "returned null".into(),
                });
            }
            for (i, p) in mesh.positions.iter().enumerate() {
                vb.add(i).write_unaligned(p.to_array());
            }
            for (i, t) in mesh.indices.iter().enumerate() {
                ib.add(i).write_unaligned(*t);
            }
            sys::rtcCommitGeometry(geom);
            sys::rtcAttachGeometry(scene, geom);
            sys::rtcReleaseGeometry(geom);
            sys::rtcCommitScene(scene);
            this.device.check("scene build (rtcCommitScene)")?;
            Ok(this)
        }
    }
}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: released once; the device (a field) is released after this body runs.
        unsafe { sys::rtcReleaseScene(self.scene) };
    }
}

#[inline]
fn to_rtc(r: &Ray) -> sys::RTCRay {
    debug_assert!(r.tmin >= 0.0 && r.tmin <= r.tmax, "bad ray interval {r:?}");
    sys::RTCRay {
        org_x: r.origin.x,
        org_y: r.origin.y,
        org_z: r.origin.z,
        tnear: r.tmin,
        dir_x: r.dir.x,
        dir_y: r.dir.y,
        dir_z: r.dir.z,
        time: 0.0,
        tfar: r.tmax,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

#[inline]
fn empty_hit() -> sys::RTCHit {
    sys::RTCHit {
        ng_x: 0.0,
        ng_y: 0.0,
        ng_z: 0.0,
        u: 0.0,
        v: 0.0,
        prim_id: sys::RTC_INVALID_GEOMETRY_ID,
        geom_id: sys::RTC_INVALID_GEOMETRY_ID,
        inst_id: [sys::RTC_INVALID_GEOMETRY_ID],
    }
}

#[inline]
fn from_rtc(rh: &sys::RTCRayHit) -> Option<Hit> {
    (rh.hit.geom_id != sys::RTC_INVALID_GEOMETRY_ID).then_some(Hit {
        t: rh.ray.tfar,
        tri: rh.hit.prim_id,
        u: rh.hit.u,
        v: rh.hit.v,
    })
}

/// Rays per `rtcOccluded1M` / `rtcIntersect1M` call in the stream methods.
const STREAM: usize = 64;

impl RayCaster for EmbreeScene {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let mut ctx = init_context();
        let mut rh = sys::RTCRayHit {
            ray: to_rtc(ray),
            hit: empty_hit(),
        };
        // SAFETY: committed scene, valid context and ray-hit structs of the header's layout.
        unsafe { sys::rtcIntersect1(self.scene, &mut ctx, &mut rh) };
        from_rtc(&rh)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        let mut ctx = init_context();
        let mut r = to_rtc(ray);
        // SAFETY: as in `intersect`. Embree sets `tfar = -inf` on an occluded ray.
        unsafe { sys::rtcOccluded1(self.scene, &mut ctx, &mut r) };
        r.tfar < 0.0 && r.tfar.is_infinite()
    }

    fn occluded_many(&self, rays: &[Ray], out: &mut [bool]) {
        debug_assert_eq!(rays.len(), out.len());
        let mut ctx = init_context();
        let mut buf = [to_rtc(&Ray::new(crate::Vec3::ZERO, crate::Vec3::X, 0.0, 0.0)); STREAM];
        for (rs, os) in rays.chunks(STREAM).zip(out.chunks_mut(STREAM)) {
            for (b, r) in buf.iter_mut().zip(rs) {
                *b = to_rtc(r);
            }
            // SAFETY: `buf` holds `rs.len()` initialised rays with stride size_of::<RTCRay>().
            unsafe {
                sys::rtcOccluded1M(
                    self.scene,
                    &mut ctx,
                    buf.as_mut_ptr(),
                    rs.len() as u32,
                    size_of::<sys::RTCRay>(),
                )
            };
            for (o, b) in os.iter_mut().zip(&buf) {
                *o = b.tfar < 0.0 && b.tfar.is_infinite();
            }
        }
    }

    fn intersect_many(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        debug_assert_eq!(rays.len(), out.len());
        let mut ctx = init_context();
        let blank = sys::RTCRayHit {
            ray: to_rtc(&Ray::new(crate::Vec3::ZERO, crate::Vec3::X, 0.0, 0.0)),
            hit: empty_hit(),
        };
        let mut buf = [blank; STREAM];
        for (rs, os) in rays.chunks(STREAM).zip(out.chunks_mut(STREAM)) {
            for (b, r) in buf.iter_mut().zip(rs) {
                *b = sys::RTCRayHit {
                    ray: to_rtc(r),
                    hit: empty_hit(),
                };
            }
            // SAFETY: as in `occluded_many`.
            unsafe {
                sys::rtcIntersect1M(
                    self.scene,
                    &mut ctx,
                    buf.as_mut_ptr(),
                    rs.len() as u32,
                    size_of::<sys::RTCRayHit>(),
                )
            };
            for (o, b) in os.iter_mut().zip(&buf) {
                *o = from_rtc(b);
            }
        }
    }

    fn name(&self) -> &'static str {
        if self.robust {
            "embree3-robust"
        } else {
            "embree3"
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn device_errors_are_reported_not_panics() {
        let device = Device::new().unwrap();
        device.check("fresh device").unwrap();
        // An invalid geometry type: Embree returns null and reports an error.
        // SAFETY: live device; Embree validates the type argument.
        let g = unsafe { sys::rtcNewGeometry(device.raw, 999) };
        assert!(g.is_null());
        let err = device.check("rtcNewGeometry").unwrap_err();
        assert!(
            matches!(&err, AccelError::Embree { call: "rtcNewGeometry", message } if message.starts_with("error ")),
            "{err:?}"
        );
        assert!(
            err.to_string()
                .starts_with("Embree: rtcNewGeometry: error "),
            "{err}"
        );
        // The error is consumed: the device is usable again.
        device.check("after the error").unwrap();
    }

    #[test]
    fn robust_and_default_scenes_report_names() {
        let m = crate::accel::bvh::tests::sphere(6, 12);
        assert_eq!(EmbreeScene::build(&m).unwrap().name(), "embree3");
        assert_eq!(
            EmbreeScene::build_robust(&m).unwrap().name(),
            "embree3-robust"
        );
    }
}
