//! The authoring side: a scene is a `hecs::World` whose entities carry [`Transform`],
//! [`Mesh`] or [`Sphere`], [`Material`] and optionally [`Emitter`]; one entity carries the
//! [`Camera`]; [`MaterialTextures`], [`VertexTangents`], [`VertexColors`] and [`PunctualLight`] come from
//! imported files. Loaders fill
//! the world; `flatten` is the only reader of it on the render side (the loaders also read the
//! worlds they build, to place imported models).

pub mod animation;
pub mod components;
pub mod load;

pub use animation::AnimationChoice;
pub use components::{
    AlphaCoverage, AlphaMode, Camera, Emitter, EnvironmentLight, EnvironmentSource, FresnelModel,
    Iridescence, Material, MaterialAnisotropy, MaterialTextures, Mesh, Name, Projection,
    PunctualLight, SharedMesh, Sphere, SpotFalloff, TextureSlot, Transform, VertexColors,
    VertexTangents, Volume, mesh_of,
};
pub use load::{Scene, load_scene, load_scene_str};
