//! Denoising of the resolved film with Intel Open Image Denoise (OIDN) 2.x, in builds with the
//! cargo feature `denoise`: the RT filter on the HDR colour, guided by the albedo and normal
//! layers, which are first denoised themselves (OIDN's "clean aux" path, its best quality for
//! final frames). Without the feature [`denoise`] reports that the build has no denoiser.
//!
//! Determinism: the CPU device runs on a fixed number of its own threads, whatever the
//! renderer's thread count ([`OIDN_THREADS`]); the same film gives the same image on a given
//! machine. OIDN picks its kernels by the processor's instruction set, so two machines of
//! different kinds (AVX2, AVX-512) may differ in the last bits.

use crate::film::Image;

/// Whether this build can denoise (the cargo feature `denoise`).
pub const AVAILABLE: bool = cfg!(feature = "denoise");

/// Threads of OIDN's CPU device. Fixed, so that `--threads` cannot change the result even if
/// OIDN's work split were to depend on it; two threads, the machine's cores on the reference
/// machine (the filter takes about a second at 800x800 there).
pub const OIDN_THREADS: i32 = 2;

/// Why a denoise failed (the library could not make a device or run the filter).
#[derive(Debug, thiserror::Error)]
#[error("denoising failed: {0}")]
pub struct DenoiseError(pub String);

/// The denoised `color`, guided by `albedo` (in [0, 1]) and `normal` (unit or zero vectors);
/// all three of one size.
pub fn denoise(color: &Image, albedo: &Image, normal: &Image) -> Result<Image, DenoiseError> {
    let size = (color.width, color.height);
    if (albedo.width, albedo.height) != size || (normal.width, normal.height) != size {
        return Err(DenoiseError(
            "the guide layers differ in size from the image".into(),
        ));
    }
    oidn_filter::denoise(color, albedo, normal)
}

/// [`denoise`] of `color` without its part `direct` (the light the camera sees directly or
/// through mirrors and glass, `film::Layer::Emission`), which is added back unchanged. That
/// part has no noise but the coverage of the lights' edges, which the filter would blur into
/// their surroundings: on the room at 256x256 (Sobol, denoised default), denoising the whole
/// colour made the MSE of the pixels on the ceiling light 6x that of the noisy input
/// (docs/denoising.md).
pub fn denoise_except(
    color: &Image,
    direct: &Image,
    albedo: &Image,
    normal: &Image,
) -> Result<Image, DenoiseError> {
    if (direct.width, direct.height) != (color.width, color.height) {
        return Err(DenoiseError(
            "the emission layer differs in size from the image".into(),
        ));
    }
    let rest = Image {
        pixels: (color.pixels.iter().zip(&direct.pixels))
            .map(|(c, d)| *c - *d)
            .collect(),
        ..*color
    };
    let mut denoised = denoise(&rest, albedo, normal)?;
    for (p, d) in denoised.pixels.iter_mut().zip(&direct.pixels) {
        *p += *d;
    }
    Ok(denoised)
}

#[cfg(not(feature = "denoise"))]
mod oidn_filter {
    use super::{DenoiseError, Image};

    pub fn denoise(_: &Image, _: &Image, _: &Image) -> Result<Image, DenoiseError> {
        Err(DenoiseError(
            "this build has no denoiser (build with --features denoise)".into(),
        ))
    }
}

#[cfg(feature = "denoise")]
#[allow(unsafe_code)]
mod oidn_filter {
    use super::{DenoiseError, Image, OIDN_THREADS};
    use crate::math::Rgb;
    use oidn::sys::*;
    use std::ffi::{CStr, c_void};

    /// A device handle, released when dropped.
    struct Device(OIDNDevice);

    impl Drop for Device {
        fn drop(&mut self) {
            // SAFETY: the handle came from oidnNewDevice and is released once.
            unsafe { oidnReleaseDevice(self.0) }
        }
    }

    /// A filter handle, released when dropped.
    struct Filter(OIDNFilter);

    impl Drop for Filter {
        fn drop(&mut self) {
            // SAFETY: the handle came from oidnNewFilter and is released once.
            unsafe { oidnReleaseFilter(self.0) }
        }
    }

    /// The error OIDN recorded on `device` (or, for a null device, the global one), if any.
    fn recorded_error(device: OIDNDevice, doing: &str) -> Result<(), DenoiseError> {
        let mut message: *const std::os::raw::c_char = std::ptr::null();
        // SAFETY: `device` is a live handle or null (the global error state).
        let code = unsafe { oidnGetDeviceError(device, &mut message) };
        if code == OIDNError_OIDN_ERROR_NONE {
            return Ok(());
        }
        let text = if message.is_null() {
            format!("error code {code}")
        } else {
            // SAFETY: OIDN returns a NUL-terminated string valid until its next call.
            unsafe { CStr::from_ptr(message) }
                .to_string_lossy()
                .into_owned()
        };
        Err(DenoiseError(format!("{doing}: {text}")))
    }

    fn new_cpu_device() -> Result<Device, DenoiseError> {
        // SAFETY: plain FFI calls on the handle OIDN returns, checked for null.
        unsafe {
            let handle = oidnNewDevice(OIDNDeviceType_OIDN_DEVICE_TYPE_CPU);
            if handle.is_null() {
                recorded_error(std::ptr::null_mut(), "cannot create OIDN's CPU device")?;
                return Err(DenoiseError("cannot create OIDN's CPU device".into()));
            }
            let device = Device(handle);
            oidnSetDeviceInt(handle, c"numThreads".as_ptr(), OIDN_THREADS);
            // Pinning threads to cores would fight the renderer's own threads.
            oidnSetDeviceBool(handle, c"setAffinity".as_ptr(), false);
            oidnCommitDevice(handle);
            recorded_error(handle, "cannot start OIDN's CPU device")?;
            Ok(device)
        }
    }

    /// One run of the RT filter: `inputs` (named images, float RGB, `width` x `height`) into
    /// `output`; `hdr` for a colour input, `clean_aux` when the guides are prefiltered.
    fn run_filter(
        device: &Device,
        inputs: &[(&CStr, &[Rgb])],
        output: &mut [Rgb],
        (width, height): (usize, usize),
        hdr: bool,
        clean_aux: bool,
    ) -> Result<(), DenoiseError> {
        // SAFETY: the images are shared (not copied) with OIDN only until the filter has run
        // and is released at the end of this function; every image holds width x height
        // pixels of three f32 each (`Rgb` is three packed f32).
        unsafe {
            let handle = oidnNewFilter(device.0, c"RT".as_ptr());
            if handle.is_null() {
                recorded_error(device.0, "cannot create OIDN's RT filter")?;
                return Err(DenoiseError("cannot create OIDN's RT filter".into()));
            }
            let filter = Filter(handle);
            let image = |name: &CStr, pixels: *mut c_void| {
                oidnSetSharedFilterImage(
                    filter.0,
                    name.as_ptr(),
                    pixels,
                    OIDNFormat_OIDN_FORMAT_FLOAT3,
                    width,
                    height,
                    0,
                    0,
                    0,
                )
            };
            for (name, pixels) in inputs {
                image(name, pixels.as_ptr() as *mut c_void);
            }
            image(c"output", output.as_mut_ptr() as *mut c_void);
            oidnSetFilterBool(filter.0, c"hdr".as_ptr(), hdr);
            oidnSetFilterBool(filter.0, c"cleanAux".as_ptr(), clean_aux);
            oidnCommitFilter(filter.0);
            recorded_error(device.0, "cannot set up OIDN's RT filter")?;
            oidnExecuteFilter(filter.0);
            recorded_error(device.0, "OIDN's RT filter failed")
        }
    }

    pub fn denoise(color: &Image, albedo: &Image, normal: &Image) -> Result<Image, DenoiseError> {
        let size = (color.width as usize, color.height as usize);
        let device = new_cpu_device()?;
        let n = color.pixels.len();
        let mut clean_albedo = vec![Rgb::ZERO; n];
        run_filter(
            &device,
            &[(c"albedo", &albedo.pixels)],
            &mut clean_albedo,
            size,
            false,
            false,
        )?;
        let mut clean_normal = vec![Rgb::ZERO; n];
        run_filter(
            &device,
            &[(c"normal", &normal.pixels)],
            &mut clean_normal,
            size,
            false,
            false,
        )?;
        // OIDN's input must be finite.
        let finite: Vec<Rgb> = color
            .pixels
            .iter()
            .map(|p| {
                if p.is_finite() {
                    p.max(Rgb::ZERO)
                } else {
                    Rgb::ZERO
                }
            })
            .collect();
        let mut output = vec![Rgb::ZERO; n];
        run_filter(
            &device,
            &[
                (c"color", &finite),
                (c"albedo", &clean_albedo),
                (c"normal", &clean_normal),
            ],
            &mut output,
            size,
            true,
            true,
        )?;
        Ok(Image {
            width: color.width,
            height: color.height,
            pixels: output,
        })
    }
}
