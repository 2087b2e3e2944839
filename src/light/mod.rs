//! Lights, portals, the antishadow classifier and the sampling strategies.

pub mod antishadow;
