//! Scene descriptions — plain data, what glTF files and the built-in scenes produce — and the
//! readers and writers that make them. Nothing here knows how a scene is traced.

pub mod builtin;
pub mod desc;
pub mod environment;
pub mod gltf;
pub mod texture;
