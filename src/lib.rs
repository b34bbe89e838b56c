//! # wavetrace
//!
//! A physically based Monte Carlo path tracer. Data flows one way:
//!
//! ```text
//! scene file --load_scene--> hecs::World --flatten--> FlatScene (SoA primitives + one BVH)
//!   --render (wavefront stages: generate, intersect, shade, shadow)--> Film --write_image--> file
//! ```
//!
//! ```no_run
//! use wavetrace::{RenderSettings, flatten, load_scene, render, write_image, Flow};
//! let path = std::path::Path::new("scenes/room.toml");
//! let scene = load_scene(path)?;
//! let flat = flatten(&scene.world, path)?;
//! let settings = RenderSettings { width: 200, height: 200, spp: 4, ..Default::default() };
//! let (film, stats) = render(&flat, &settings, |_| Flow::Continue)?;
//! write_image(std::path::Path::new("room.png"), &film, 0.0)?;
//! println!("{}", stats.summary());
//! # Ok::<(), wavetrace::Error>(())
//! ```
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod bsdf;
pub mod camera;
pub mod error;
pub mod film;
pub mod flatten;
pub mod image_error;
pub mod lights_environment;
pub mod math;
pub mod output;
pub mod scene;
pub mod settings;
pub mod texture;
pub mod wavefront;

pub use error::{Error, Result};
pub use film::{Film, Image, Pixels};
pub use flatten::{FlatScene, flatten};
pub use output::write_image;
pub use scene::{Scene, load_scene};
pub use settings::RenderSettings;
pub use wavefront::stats::RenderStats;
pub use wavefront::{Flow, Progress, render};
