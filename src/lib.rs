//! portalview: light portals for area lights (Romeu Huidobro 2022), generalised to convex
//! polygons in any orientation, with a progressive CPU path tracer and an interactive viewer.
//!
//! The maths of the method lives in [`light`]; domain-free sampling in [`sampling`].

#![forbid(unsafe_code)]

pub mod app;
pub mod bench;
pub mod cli;
pub mod compare;
pub mod light;
pub mod material;
pub mod render;
pub mod sampling;
pub mod scene;
