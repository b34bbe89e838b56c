//! The authoring side: a scene is a `hecs::World` whose entities carry [`Transform`],
//! [`Mesh`] or [`Sphere`], [`Material`] and optionally [`Emitter`]; one entity carries the
//! [`Camera`]. Loaders fill the world; `flatten` is the only reader of it.

pub mod components;
pub mod load;

pub use components::{Camera, Emitter, FresnelModel, Material, Mesh, Name, Sphere, Transform};
pub use load::{Scene, load_scene, load_scene_str};
