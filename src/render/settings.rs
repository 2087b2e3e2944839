//! What a render is asked to do: the settings every command, the viewer and the comparisons
//! hand the integrator.

use crate::light::{Mixture, Selection, Strategy};
use crate::sampling::SamplerKind;

/// What a render is asked to do.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub strategy: Strategy,
    /// Replaces every portal's alpha when set.
    pub alpha: Option<f32>,
    /// Path vertices after the camera: 1 = direct light only (the thesis's experiments).
    pub max_depth: u32,
    pub seed: u64,
    /// Where the random numbers come from.
    pub sampler: SamplerKind,
    /// One sample of the light mixture per shading point, or one from each share.
    pub mixture: Mixture,
    /// How a shading point picks the light it samples.
    pub selection: Selection,
    /// Whether shadow rays cross thin glass or stop at it.
    pub glass: GlassShadows,
    /// Whether paths continue through the portals as well as by the BSDF.
    pub bounces: GuideBounces,
}

/// Whether a path's next direction may be drawn through the portals (guided continuation,
/// `docs/method.md` §12) or from the BSDF alone.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
pub enum GuideBounces {
    /// From a mixture of the BSDF and the openings bounced light leaves by: lamps' portals,
    /// and windows with something outside them.
    #[default]
    On,
    /// From the BSDF alone (light bounced inside a shade is found by chance).
    Off,
}

impl GuideBounces {
    pub const ALL: [GuideBounces; 2] = [GuideBounces::On, GuideBounces::Off];

    pub fn label(self) -> &'static str {
        match self {
            GuideBounces::On => "on",
            GuideBounces::Off => "off",
        }
    }
}

/// What a shadow ray does at smooth thin-walled glass (a pane, a globe's shell). BSDF paths
/// cross it either way, as a null interface that is not a path vertex.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
pub enum GlassShadows {
    /// Through it, weighted by its straight-through transmittance: lights and windows behind
    /// glass are sampled as if the glass were a filter (docs/method.md §6.3).
    #[default]
    Pass,
    /// Stopped, as in Cycles: light reaches the far side of glass along BSDF paths only (whose
    /// emission after a pane then takes the full weight, as light sampling could not reach it).
    Stop,
}

impl GlassShadows {
    pub const ALL: [GlassShadows; 2] = [GlassShadows::Pass, GlassShadows::Stop];

    pub fn label(self) -> &'static str {
        match self {
            GlassShadows::Pass => "pass",
            GlassShadows::Stop => "stop",
        }
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            strategy: Strategy::Antishadow,
            alpha: None,
            max_depth: 1,
            seed: 0,
            sampler: SamplerKind::default(),
            mixture: Mixture::default(),
            selection: Selection::default(),
            glass: GlassShadows::default(),
            bounces: GuideBounces::default(),
        }
    }
}
