//! Colours of the antishadow regions and techniques, and the overlay image built from the
//! worker's per-pixel classification.

use egui::{Color32, ColorImage};
use serde::{Deserialize, Serialize};

use crate::light::antishadow::Region;
use crate::light::sky::SkyTechnique;
use crate::light::{Strategy, Technique};
use crate::render::primary::PrimaryBuffer;

/// Which overlay is drawn over the render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum OverlayKind {
    #[default]
    None,
    /// The antishadow region of each pixel's primary hit.
    Regions,
    /// The technique the antishadow mode uses at each pixel's primary hit.
    Techniques,
}

impl OverlayKind {
    pub const ALL: [OverlayKind; 3] = [
        OverlayKind::None,
        OverlayKind::Regions,
        OverlayKind::Techniques,
    ];

    pub fn name(self) -> &'static str {
        match self {
            OverlayKind::None => "none",
            OverlayKind::Regions => "regions",
            OverlayKind::Techniques => "strategy used",
        }
    }
}

/// A region's colour; a technique shares the colour of the region that uses it.
pub(crate) fn region_colour(region: Region) -> Color32 {
    match region {
        Region::Behind => Color32::from_rgb(128, 128, 128),
        Region::Outside => Color32::from_rgb(70, 80, 200),
        Region::Antiumbra => Color32::from_rgb(50, 200, 90),
        Region::Antipenumbra => Color32::from_rgb(245, 200, 40),
        Region::Antiantumbra => Color32::from_rgb(235, 80, 60),
    }
}

/// The legend's line for `region`: what the antishadow mode samples there, for area-light
/// portals (`areas`) and for windows (`windows`) among the portals the legend describes. A
/// window has two regions only, and in front of it (its antiantumbra) antishadow samples the
/// environment within it, which counts as projection, where an area-light portal's
/// antiantumbra uses the portal technique.
pub(crate) fn legend_line(region: Region, areas: bool, windows: bool) -> String {
    let name = |t: Option<Technique>| technique_name(t, Some(region));
    let area = name(Strategy::Antishadow.technique(region));
    let window = match region {
        Region::Antiantumbra => Some(name(
            SkyTechnique::of(Strategy::Antishadow, true).map(SkyTechnique::technique),
        )),
        Region::Behind => Some(name(None)),
        _ => None,
    };
    let what = match window {
        Some(w) if windows && !areas => w.to_owned(),
        Some(w) if windows && w != area => format!("{area}; windows: {w}"),
        _ => area.to_owned(),
    };
    format!("{}: {what}", region.name())
}

/// What the antishadow mode samples at a point whose portal share uses `technique` and whose
/// combined region is `region`. Without a technique, a point behind every portal (or with no
/// portal) samples the light alone; a point outside every antishadow draws only the light's
/// alpha share, and nothing otherwise (`docs/method.md` §5).
pub(crate) fn technique_name(technique: Option<Technique>, region: Option<Region>) -> &'static str {
    match (technique, region) {
        (Some(t), _) => t.name(),
        (None, Some(Region::Outside)) => "light, α share",
        (None, _) => "light alone",
    }
}

/// The *strategy used* overlay's colour: the legend's colour of the region whose line names
/// what is sampled, as [`technique_name`] does (`region` is the combined region).
pub(crate) fn technique_colour(technique: Option<Technique>, region: Option<Region>) -> Color32 {
    match (technique, region) {
        (Some(Technique::Light), _) => region_colour(Region::Antiumbra),
        (Some(Technique::Portal), _) => region_colour(Region::Antiantumbra),
        (Some(Technique::Projection), _) => region_colour(Region::Antipenumbra),
        (None, Some(Region::Outside)) => region_colour(Region::Outside),
        (None, _) => region_colour(Region::Behind),
    }
}

/// The overlay as an image with `opacity` in [0, 1]; pixels that see nothing stay clear.
pub(crate) fn overlay_image(
    primary: &PrimaryBuffer,
    kind: OverlayKind,
    portal: Option<usize>,
    opacity: f32,
) -> ColorImage {
    let alpha = (opacity.clamp(0.0, 1.0) * 255.0) as u8;
    let pixels = (0..primary.combined.len())
        .map(|i| {
            let colour = match kind {
                OverlayKind::None => None,
                OverlayKind::Regions => primary.region(i, portal).map(region_colour),
                OverlayKind::Techniques => primary
                    .points
                    .get(i)
                    .copied()
                    .flatten()
                    .map(|_| technique_colour(primary.technique[i], primary.region(i, None))),
            };
            match colour {
                Some(c) => Color32::from_rgba_unmultiplied(c.r(), c.g(), c.b(), alpha),
                None => Color32::TRANSPARENT,
            }
        })
        .collect();
    ColorImage::new([primary.width as usize, primary.height as usize], pixels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legend_names_what_windows_sample() {
        // Area-light portals: the thesis's table.
        assert_eq!(
            legend_line(Region::Antiantumbra, true, false),
            "antiantumbra: portal"
        );
        assert_eq!(
            legend_line(Region::Antiumbra, true, false),
            "antiumbra: light"
        );
        assert_eq!(
            legend_line(Region::Behind, true, false),
            "behind: light alone"
        );
        // Outside every antishadow only the alpha share draws: not the light alone, and the
        // *strategy used* overlay gives it the colour of that line.
        assert_eq!(
            legend_line(Region::Outside, true, false),
            "outside: light, α share"
        );
        assert_eq!(
            technique_colour(None, Some(Region::Outside)),
            region_colour(Region::Outside)
        );
        assert_eq!(
            technique_colour(None, Some(Region::Behind)),
            region_colour(Region::Behind)
        );
        // Windows: the environment within the window, counted as projection.
        assert_eq!(
            legend_line(Region::Antiantumbra, false, true),
            "antiantumbra: projection"
        );
        assert_eq!(
            legend_line(Region::Behind, false, true),
            "behind: light alone"
        );
        // Both kinds: the line says where they differ.
        assert_eq!(
            legend_line(Region::Antiantumbra, true, true),
            "antiantumbra: portal; windows: projection"
        );
        assert_eq!(
            legend_line(Region::Antipenumbra, true, true),
            "antipenumbra: projection"
        );
        // No portal at all: the area table, as before.
        assert_eq!(
            legend_line(Region::Antiantumbra, false, false),
            "antiantumbra: portal"
        );
    }
}
