//! # wavetrace
//!
//! A physically based Monte Carlo path tracer. Data flows one way (see
//! `docs/architecture.md` for the code map):
//!
//! ```text
//! scene file --load_scene--> hecs::World --flatten--> RenderScene (SoA primitives + one BVH)
//!   --render (wavefront stages: generate, intersect, shade, shadow)--> Film --write_image--> file
//! ```
//!
//! The public front door: [`load_scene`], [`flatten`], [`RenderSettings::resolve`] (the
//! scene's `[render]` settings under the caller's overrides), [`render`], [`write_image`].
//!
//! ```no_run
//! use wavetrace::{RenderOverrides, RenderSettings, flatten, load_scene, render, write_image, Flow};
//! let path = std::path::Path::new("scenes/room.toml");
//! let scene = load_scene(path)?;
//! let flat = flatten(&scene.world, path)?;
//! let overrides = RenderOverrides { width: Some(200), spp: Some(4), ..Default::default() };
//! let settings = RenderSettings::resolve(&scene.defaults, &overrides, flat.camera().aspect_ratio);
//! let (film, stats) = render(&flat, &settings, |_| Flow::Continue)?;
//! write_image(std::path::Path::new("room.png"), &film, 0.0)?;
//! println!("{}", stats.summary());
//! # Ok::<(), wavetrace::Error>(())
//! ```
#![warn(missing_docs)]
// Unsafe code is forbidden, but for the calls into Open Image Denoise (`denoise`, in builds
// with that feature), which allow it in that one module.
#![cfg_attr(not(feature = "denoise"), forbid(unsafe_code))]
#![cfg_attr(feature = "denoise", deny(unsafe_code))]

pub(crate) mod accel;
pub(crate) mod bsdf;
pub(crate) mod camera;
pub mod denoise;
pub mod error;
pub mod farm;
pub mod film;
pub mod filter;
pub(crate) mod flatten;
pub mod frames;
pub(crate) mod geometry;
pub(crate) mod lights;
pub mod math;
pub(crate) mod memory;
pub mod output;
pub(crate) mod ray_cone;
pub(crate) mod render_scene;
pub mod scene;
pub mod settings;
pub(crate) mod texture;
pub(crate) mod wavefront;

pub use error::{Error, Result};
pub use film::{Film, Image, Pixels};
pub use filter::{FilterKind, PixelFilter};
pub use flatten::{INSTANCE_MIN_TRIANGLES, INSTANCE_MIN_USES, Instancing, flatten, flatten_with};
pub use output::write_image;
pub use render_scene::{FlattenTimes, RenderScene};
pub use scene::{Scene, load_scene};
pub use settings::{RenderOverrides, RenderSettings};
pub use wavefront::stats::RenderStats;
pub use wavefront::{Flow, Progress, render, render_rows};

/// The renderer's internals, for the stage benchmarks, the examples and the end-to-end tests
/// only. **Unstable**: anything here may change or go away without notice; programs use the
/// items at the crate root.
#[doc(hidden)]
pub mod internals {
    pub use crate::bsdf::Bsdf;
    pub use crate::bsdf::sheen::albedo as sheen_albedo;
    pub use crate::camera::PinholeCamera;
    pub use crate::geometry::Shape;
    pub use crate::lights::LightTable;
    pub use crate::lights::environment::Environment;
    pub use crate::memory::trace_phase;
    pub use crate::render_scene::{PACKET_SIZE, Packet, Ray, TraversalStack};
    pub use crate::texture::{MinFilter, Mipmapped, SurfaceTextures, Texture, TextureRef};
    pub use crate::wavefront::batch::{HitBatch, PathState, RayBatch, ShadowBatch};
    pub use crate::wavefront::generate::generate_camera_rays;
    pub use crate::wavefront::intersect::intersect_closest;
    pub use crate::wavefront::params::ShadeParams;
    pub use crate::wavefront::shade::shade_hits;
    pub use crate::wavefront::shadow::trace_shadow_rays;
}
