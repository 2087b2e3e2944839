//! What the viewer remembers between runs, and what the window shows.

use serde::{Deserialize, Serialize};

use crate::light::{Mixture, Selection, Strategy};
use crate::render::integrator::{GlassShadows, GuideBounces};
use crate::sampling::SamplerKind;

use super::compare_view::CompareViewSettings;
use super::overlay::OverlayKind;

/// What persists between runs (eframe storage).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ViewerSettings {
    pub strategy: Strategy,
    /// Overrides every portal's alpha when set.
    pub alpha: Option<f32>,
    pub max_depth: u32,
    /// Where the render's random numbers come from.
    pub sampler: SamplerKind,
    /// How a shading point draws from its light mixture.
    pub mixture: Mixture,
    /// How a shading point picks the light it samples (settings saved before it existed
    /// load with the default, as the container's `serde(default)` fills missing fields).
    pub selection: Selection,
    /// What shadow rays do at thin glass.
    pub glass: GlassShadows,
    /// Whether paths continue through the portals as well as by the BSDF.
    pub bounces: GuideBounces,
    /// Exposure in stops.
    pub exposure: f32,
    /// Show log-luminance in false colour instead of the tone-mapped image.
    pub false_colour: bool,
    /// Render resolution relative to the viewport's physical pixels.
    pub resolution_scale: f32,
    /// The scene opened last: a built-in name or a file path.
    pub scene: String,
    /// Files opened recently, newest first.
    pub recent: Vec<String>,
    pub overlay: OverlayKind,
    pub overlay_opacity: f32,
    /// Portal and light outlines over the image.
    pub show_outlines: bool,
    /// Edges of the antishadow volumes over the image.
    pub show_volumes: bool,
    /// Classify the overlay's regions with the brute-force classifier (debug).
    pub brute_force_regions: bool,
    /// The comparison mode's settings.
    pub compare: CompareViewSettings,
}

impl Default for ViewerSettings {
    fn default() -> Self {
        ViewerSettings {
            strategy: Strategy::Antishadow,
            alpha: None,
            // One bounce more than the thesis's direct-only experiments, so that surfaces lit
            // only indirectly (the outside of a lampshade) are visible in the viewer.
            max_depth: 2,
            sampler: SamplerKind::default(),
            mixture: Mixture::default(),
            selection: Selection::default(),
            glass: GlassShadows::default(),
            bounces: GuideBounces::default(),
            exposure: 0.0,
            false_colour: false,
            resolution_scale: 0.5,
            scene: DEFAULT_SCENE.into(),
            recent: Vec::new(),
            overlay: OverlayKind::None,
            overlay_opacity: 0.5,
            show_outlines: true,
            show_volumes: false,
            brute_force_regions: false,
            compare: CompareViewSettings::default(),
        }
    }
}

/// The scene shown when nothing else is asked for, or when the one asked for fails to load.
pub const DEFAULT_SCENE: &str = "lampshade";

/// How many recent files are remembered.
const RECENT: usize = 8;

impl ViewerSettings {
    /// Puts a file opened just now first among the recent ones.
    pub(super) fn remember(&mut self, file: &str) {
        self.recent.retain(|r| r != file);
        self.recent.insert(0, file.to_owned());
        self.recent.truncate(RECENT);
    }
}

/// What the window shows: the progressive render of one strategy, or the equal-time
/// comparison of the strategies against a reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewMode {
    #[default]
    Render,
    Compare,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Settings saved before light selection existed still load, with the default selection
    /// and everything they do hold kept.
    #[test]
    fn settings_without_a_selection_load() {
        let mut saved = serde_json::to_value(ViewerSettings {
            mixture: Mixture::EachShare,
            selection: Selection::Power,
            ..ViewerSettings::default()
        })
        .unwrap();
        saved.as_object_mut().unwrap().remove("selection");
        let loaded: ViewerSettings = serde_json::from_value(saved).unwrap();
        assert_eq!(loaded.selection, Selection::Tree);
        assert_eq!(loaded.mixture, Mixture::EachShare);
    }
}
