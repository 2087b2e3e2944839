//! `portalview view`: the viewer's start-up options.

use clap::Args;

use super::EnvironmentArgs;
use crate::app::ViewOptions;
use crate::app::overlay::OverlayKind;
use crate::light::{Mixture, Selection, Strategy};
use crate::render::integrator::{GlassShadows, GuideBounces};
use crate::sampling::SamplerKind;

#[derive(Args, Debug, Clone, Default)]
pub struct ViewArgs {
    /// Built-in name (lampshade, fig8a, fig8b, fig8c, window, windows2, desklamp, livingroom,
    /// panes, pendant) or a .gltf/.glb path.
    pub scene: Option<String>,
    /// Start with this strategy (else the one used last).
    #[arg(long, value_enum)]
    pub strategy: Option<Strategy>,
    /// Start with this overlay over the image.
    #[arg(long, value_enum)]
    pub overlay: Option<OverlayKind>,
    /// Draw the edges of the antishadow volumes.
    #[arg(long)]
    pub volumes: bool,
    /// Path vertices after the camera (else the value used last).
    #[arg(long)]
    pub max_depth: Option<u32>,
    /// Random numbers: Owen-scrambled Sobol' points or independent ones (else the one used
    /// last).
    #[arg(long, value_enum)]
    pub sampler: Option<SamplerKind>,
    /// How a shading point draws from its light mixture (else the one used last).
    #[arg(long, value_enum)]
    pub mixture: Option<Mixture>,
    /// How a shading point picks the light it samples (else the one used last).
    #[arg(long, value_enum)]
    pub light_selection: Option<Selection>,
    /// What shadow rays do at thin glass: pass through it or stop, as in Cycles (else the one
    /// used last).
    #[arg(long, value_enum)]
    pub glass_shadows: Option<GlassShadows>,
    /// Whether bounces are guided through the portals (else as used last).
    #[arg(long, value_enum)]
    pub guide_bounces: Option<GuideBounces>,
    /// The start-up scene's sky, as for `render` (replaces the scene's).
    #[command(flatten)]
    pub environment: EnvironmentArgs,
}

impl From<ViewArgs> for ViewOptions {
    fn from(a: ViewArgs) -> Self {
        ViewOptions {
            scene: a.scene,
            strategy: a.strategy,
            overlay: a.overlay,
            volumes: a.volumes,
            max_depth: a.max_depth,
            sampler: a.sampler,
            mixture: a.mixture,
            selection: a.light_selection,
            glass: a.glass_shadows,
            bounces: a.guide_bounces,
            environment: (&a.environment).into(),
        }
    }
}
