//! The newest frame from the render worker and what is drawn from it: the tone-mapped (or
//! false-colour) texture, the overlay texture, and the legends' pixel shares.

use egui::{Color32, ColorImage, TextureHandle, TextureOptions};

use super::overlay::{self, OverlayKind};
use crate::render::tonemap;
use crate::render::worker::Frame;

/// What the overlay texture shows: (generation, kind, portal, opacity in thousandths).
type OverlayKey = (u64, OverlayKind, Option<usize>, u32);

/// What the legend's shares were computed for: (frame generation, portal or all).
type LegendKey = (u64, Option<usize>);

#[derive(Default)]
pub(super) struct FrameView {
    /// The frame on screen, kept to re-tone-map when exposure changes.
    pub frame: Option<Frame>,
    pub texture: Option<TextureHandle>,
    pub overlay_texture: Option<TextureHandle>,
    overlay_key: Option<OverlayKey>,
    /// The legend's pixel shares per region, and what they are for.
    legend: Option<(LegendKey, [f32; 5])>,
    /// The light selection legend's pixel shares per bucket, and the frame generation.
    spread_legend: Option<(u64, [f32; overlay::SPREAD_BUCKETS.len()])>,
}

impl FrameView {
    /// Whether `frame` differs from the one on screen.
    pub fn is_new(&self, frame: &Frame) -> bool {
        self.frame.as_ref().is_none_or(|f| {
            (f.generation, f.spp, f.preview) != (frame.generation, frame.spp, frame.preview)
        })
    }

    /// Tone-maps the frame on screen into the render texture.
    pub fn upload(&mut self, ctx: &egui::Context, exposure: f32, false_colour: bool) {
        let Some(frame) = &self.frame else {
            return;
        };
        let pixels: Vec<Color32> = if false_colour {
            false_colour_pixels(&frame.pixels)
        } else {
            frame
                .pixels
                .iter()
                .map(|&c| {
                    let [r, g, b] = tonemap::to_srgb8(c, exposure);
                    Color32::from_rgb(r, g, b)
                })
                .collect()
        };
        let image = ColorImage::new([frame.width as usize, frame.height as usize], pixels);
        match &mut self.texture {
            Some(t) => t.set(image, TextureOptions::LINEAR),
            None => self.texture = Some(ctx.load_texture("render", image, TextureOptions::LINEAR)),
        }
    }

    /// Rebuilds the overlay texture when what it shows changed.
    pub fn update_overlay(
        &mut self,
        ctx: &egui::Context,
        kind: OverlayKind,
        portal: Option<usize>,
        opacity: f32,
    ) {
        let Some(frame) = &self.frame else {
            return;
        };
        let Some(primary) = &frame.primary else {
            return;
        };
        let key = (frame.generation, kind, portal, (opacity * 1000.0) as u32);
        if self.overlay_key == Some(key) {
            return;
        }
        self.overlay_key = Some(key);
        let image = overlay::overlay_image(primary, kind, portal, opacity);
        match &mut self.overlay_texture {
            Some(t) => t.set(image, TextureOptions::NEAREST),
            None => {
                self.overlay_texture =
                    Some(ctx.load_texture("overlay", image, TextureOptions::NEAREST))
            }
        }
    }

    /// The share of the frame's pixels in each region of `portal` (or of all portals),
    /// computed once per frame generation.
    pub fn shares(&mut self, portal: Option<usize>) -> Option<[f32; 5]> {
        let f = self.frame.as_ref()?;
        let key = (f.generation, portal);
        match self.legend {
            Some((k, shares)) if k == key => Some(shares),
            _ => {
                let shares = f.primary.as_ref()?.shares(portal);
                self.legend = Some((key, shares));
                Some(shares)
            }
        }
    }

    /// The share of the frame's pixels in each bucket of the light selection's spread,
    /// computed once per frame generation.
    pub fn spread_shares(&mut self) -> Option<[f32; overlay::SPREAD_BUCKETS.len()]> {
        let f = self.frame.as_ref()?;
        match self.spread_legend {
            Some((generation, shares)) if generation == f.generation => Some(shares),
            _ => {
                let shares = overlay::spread_shares(f.primary.as_ref()?);
                self.spread_legend = Some((f.generation, shares));
                Some(shares)
            }
        }
    }
}

/// log10 luminance over four decades below the brightest pixel, in false colour.
fn false_colour_pixels(pixels: &[glam::Vec3]) -> Vec<Color32> {
    let lum: Vec<f32> = pixels
        .iter()
        .map(|&c| crate::light::area::luminance(c))
        .collect();
    let max = lum.iter().copied().fold(0.0, f32::max).max(1e-12);
    lum.iter()
        .map(|&l| {
            let t = if l > 0.0 {
                1.0 + (l / max).log10() / 4.0
            } else {
                0.0
            };
            let [r, g, b] = tonemap::false_colour(t);
            Color32::from_rgb(r, g, b)
        })
        .collect()
}
