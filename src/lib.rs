//! portalview: light portals for area lights (Romeu Huidobro 2022), generalised to convex
//! polygons in any orientation, with a progressive CPU path tracer and an interactive viewer.
//!
//! The method is explained in `docs/method.md`; its maths lives in [`light`], domain-free
//! sampling in [`sampling`].
//!
//! Layers, bottom to top; a module imports only from the layers below it:
//!
//! ```text
//! io, isa, camera, sampling, asset  files, CPU features, the pinhole camera, warps and polygons, scene descriptions
//! material, surface, light          the BSDF and its textures at a point; area lights, portals, regions, strategies
//! scene                             a validated scene ready to trace (triangles, BVH, lights)
//! render                            integrator, passes, film, statistics, background workers
//! compare                           metrics, references, equal-time comparison and its worker
//! app                               the eframe viewer
//! cli                               command-line parsing and the subcommands (nothing imports it)
//! ```

// `unsafe` in two places: the tile renderer compiled for AVX2 (x86-64-v3) and the BVH's AVX2 node
// test, each called only after the CPU was checked for them (`render::render_tile_scheduled`,
// `scene::bvh::node_hits`).
#![deny(unsafe_code)]

pub mod app;
pub mod asset;
pub mod camera;
pub mod cli;
pub mod compare;
pub mod io;
pub mod isa;
pub mod light;
pub mod material;
pub mod render;
pub mod sampling;
pub mod scene;
pub mod surface;
