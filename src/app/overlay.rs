//! Colours of the antishadow regions and techniques and of the light selection's spread, and
//! the overlay image built from the worker's per-pixel classification.

use egui::{Color32, ColorImage};
use serde::{Deserialize, Serialize};

use crate::light::antishadow::Region;
use crate::light::sky::SkyTechnique;
use crate::light::{Strategy, Technique};
use crate::render::primary::{PrimaryBuffer, SPREAD_SHARE};

/// Which overlay is drawn over the render.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum OverlayKind {
    #[default]
    None,
    /// The antishadow region of each pixel's primary hit.
    Regions,
    /// The technique the antishadow mode uses at each pixel's primary hit.
    Techniques,
    /// How many lights carry most of the light tree's picks at each pixel's primary hit.
    LightSelection,
}

impl OverlayKind {
    pub const ALL: [OverlayKind; 4] = [
        OverlayKind::None,
        OverlayKind::Regions,
        OverlayKind::Techniques,
        OverlayKind::LightSelection,
    ];

    pub fn name(self) -> &'static str {
        match self {
            OverlayKind::None => "none",
            OverlayKind::Regions => "regions",
            OverlayKind::Techniques => "strategy used",
            OverlayKind::LightSelection => "light selection",
        }
    }
}

/// The *light selection* overlay's buckets of [`PrimaryBuffer::spread`], as (fewest, most)
/// lights: doubling widths, since what matters is one light against a few against many.
pub(crate) const SPREAD_BUCKETS: [(u32, u32); 6] =
    [(1, 1), (2, 2), (3, 4), (5, 8), (9, 15), (16, u32::MAX)];

/// The buckets' colours, dark blue to yellow, brighter with more lights (readable without
/// telling hues apart).
const SPREAD_COLOURS: [Color32; 6] = [
    Color32::from_rgb(25, 35, 120),
    Color32::from_rgb(35, 85, 175),
    Color32::from_rgb(30, 140, 160),
    Color32::from_rgb(60, 180, 110),
    Color32::from_rgb(170, 210, 50),
    Color32::from_rgb(250, 230, 40),
];

/// The bucket of `lights` lights carrying the share (0 counts as 1: it never occurs).
pub(crate) fn spread_bucket(lights: u32) -> usize {
    SPREAD_BUCKETS
        .iter()
        .position(|&(_, most)| lights <= most)
        .unwrap_or(SPREAD_BUCKETS.len() - 1)
}

/// The colour of a pixel whose hit has `lights` lights carrying the share.
pub fn spread_colour(lights: u32) -> Color32 {
    SPREAD_COLOURS[spread_bucket(lights)]
}

/// The legend's colour and name of bucket `k`.
pub(crate) fn spread_legend(k: usize) -> (Color32, String) {
    let (fewest, most) = SPREAD_BUCKETS[k];
    let name = match (fewest, most) {
        (1, 1) => "1 light".to_owned(),
        (f, u32::MAX) => format!("{f} or more lights"),
        (f, m) if f == m => format!("{f} lights"),
        (f, m) => format!("{f}–{m} lights"),
    };
    (SPREAD_COLOURS[k], name)
}

/// The share of the pixels with a spread in each bucket, among those that have one.
pub(crate) fn spread_shares(primary: &PrimaryBuffer) -> [f32; SPREAD_BUCKETS.len()] {
    let mut counts = [0usize; SPREAD_BUCKETS.len()];
    for &lights in primary.spread.iter().flatten() {
        counts[spread_bucket(lights)] += 1;
    }
    let total = counts.iter().sum::<usize>().max(1);
    counts.map(|c| c as f32 / total as f32)
}

/// What the *light selection* overlay shows, for its legend and hover text. The worker
/// classifies with the antishadow strategy's default sampler, so the overlay shows its tree
/// whatever the render's strategy and light selection.
pub(crate) fn spread_caption() -> String {
    format!(
        "How many lights carry {:.0}% of the light tree's picks at each pixel's hit: 1 where \
         one light takes nearly every sample, more where the picks spread. It shows the tree \
         as the antishadow strategy builds it (portals bounding the lights behind them), \
         whatever the strategy and light selection above. Pixels that see nothing, or that no \
         light reaches, stay clear.",
        100.0 * SPREAD_SHARE
    )
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
                OverlayKind::LightSelection => {
                    primary.spread.get(i).copied().flatten().map(spread_colour)
                }
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

    #[test]
    fn spread_buckets_cover_every_count_once() {
        let names: Vec<String> = (0..SPREAD_BUCKETS.len())
            .map(|k| spread_legend(k).1)
            .collect();
        assert_eq!(
            names,
            [
                "1 light",
                "2 lights",
                "3–4 lights",
                "5–8 lights",
                "9–15 lights",
                "16 or more lights"
            ]
        );
        // Every count falls in the bucket whose bounds hold it, and the next count in the
        // same bucket or the next one: the buckets tile the counts.
        for lights in 1..100u32 {
            let k = spread_bucket(lights);
            let (fewest, most) = SPREAD_BUCKETS[k];
            assert!((fewest..=most).contains(&lights), "{lights} in {k}");
            assert!(spread_bucket(lights + 1) - k <= 1);
        }
        assert_eq!(spread_colour(1), SPREAD_COLOURS[0]);
        assert_eq!(spread_colour(1000), SPREAD_COLOURS[5]);
        // Brighter with more lights.
        let luma = |c: Color32| 0.2 * c.r() as f32 + 0.7 * c.g() as f32 + 0.1 * c.b() as f32;
        assert!(SPREAD_COLOURS.windows(2).all(|w| luma(w[0]) < luma(w[1])));
    }
}
