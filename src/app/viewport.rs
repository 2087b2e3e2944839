//! The image area: the render and its overlay, camera controls, portal and light outlines,
//! antishadow volume edges, picking a portal by its outline, and the pixel inspector. The
//! gizmo's handles are in `gizmo.rs`.

use egui::{Color32, Pos2, Rect, Sense, Stroke, Ui};
use glam::{Vec2, Vec3};

use super::edit::PortalEditor;
use super::frame_view::FrameView;
use super::gizmo::PortalFrame;
use super::overlay::{self, OverlayKind, region_colour};
use super::{Command, Current, PortalViewApp};
use crate::camera::Camera;
use crate::light::area::luminance;
use crate::render::primary::SPREAD_SHARE;

/// Triangles of non-polygon lights outlined in the viewport, at most (the rest is not drawn).
const MAX_LIGHT_TRIANGLES_DRAWN: usize = 4096;
use crate::sampling::polygon::ConvexPolygon;

/// Maps world points to screen points through the camera, for an image drawn in `rect`.
pub(super) struct Projector {
    pub camera: Camera,
    pub rect: Rect,
}

impl Projector {
    fn aspect(&self) -> f32 {
        self.rect.width() / self.rect.height().max(1.0)
    }

    pub fn point(&self, p: Vec3) -> Option<Pos2> {
        let ndc = self.camera.project(p, self.aspect())?;
        Some(self.to_screen(ndc))
    }

    fn segment(&self, a: Vec3, b: Vec3) -> Option<[Pos2; 2]> {
        let (na, nb) = self.camera.project_segment(a, b, self.aspect())?;
        Some([self.to_screen(na), self.to_screen(nb)])
    }

    fn to_screen(&self, ndc: Vec2) -> Pos2 {
        self.rect.min + egui::vec2(ndc.x * self.rect.width(), ndc.y * self.rect.height())
    }

    /// A screen point in normalised image coordinates, and the image's aspect ratio.
    pub fn ndc(&self, pos: Pos2) -> (Vec2, f32) {
        let ndc = Vec2::new(
            (pos.x - self.rect.min.x) / self.rect.width(),
            (pos.y - self.rect.min.y) / self.rect.height(),
        );
        (ndc, self.aspect())
    }

    /// The camera ray through a screen point.
    pub fn ray(&self, pos: Pos2) -> (Vec3, Vec3) {
        let (ndc, aspect) = self.ndc(pos);
        self.camera.ray(ndc, aspect)
    }
}

impl Current {
    /// The world polygon of the editor's portal `i` (the rendered portal's, oriented, when
    /// valid; else the raw mesh), if it forms one.
    fn portal_polygon(&self, editor: &PortalEditor, i: usize) -> Option<ConvexPolygon> {
        if let Some(p) = self.rendered.portals.iter().find(|p| p.desc_index == i) {
            return Some(p.polygon.clone());
        }
        if let Some(w) = self.rendered.windows.iter().find(|w| w.desc_index == i) {
            return Some(w.polygon.clone());
        }
        ConvexPolygon::from_triangles(&editor.portals.get(i)?.world_triangles()).ok()
    }

    /// The editor index of the portal whose outline or inside is under `pos`.
    fn portal_under(
        &self,
        editor: &PortalEditor,
        projector: &Projector,
        pos: Pos2,
    ) -> Option<usize> {
        (0..editor.portals.len()).find(|&i| {
            self.portal_polygon(editor, i).is_some_and(|p| {
                let outline: Vec<Pos2> = p
                    .vertices()
                    .iter()
                    .filter_map(|&v| projector.point(v))
                    .collect();
                let n = outline.len();
                n >= 3
                    && ((0..n).any(|k| {
                        distance_to_segment(pos, [outline[k], outline[(k + 1) % n]]) < 6.0
                    }) || inside_convex(&outline, pos))
            })
        })
    }

    fn draw_outlines(&self, editor: &PortalEditor, painter: &egui::Painter, projector: &Projector) {
        let checks = self.fresh_checks(&editor.portals);
        // Openings the light leaks through past every portal: dashed red.
        for corners in checks.into_iter().flatten().flat_map(|c| &c.leaking) {
            for k in 0..corners.len() {
                let (a, b) = (corners[k], corners[(k + 1) % corners.len()]);
                if let Some(s) = projector.segment(a, b) {
                    painter.extend(egui::Shape::dashed_line(
                        &s,
                        Stroke::new(2.0, Color32::RED),
                        6.0,
                        4.0,
                    ));
                }
            }
        }
        for i in 0..editor.portals.len() {
            let Some(p) = self.portal_polygon(editor, i) else {
                continue;
            };
            let broken = self.portal_errors.iter().any(|(e, _)| *e == i);
            // A checked portal no light passes is as wrong as a broken one.
            let useless = checks.is_some_and(|checks| {
                checks
                    .iter()
                    .flat_map(|c| c.useless())
                    .any(|p| p.desc_index == i)
            });
            let colour = if broken || useless {
                Color32::RED
            } else if editor.selected == Some(i) {
                Color32::from_rgb(255, 230, 80)
            } else {
                Color32::from_rgb(80, 220, 255)
            };
            for (a, b) in p.edges() {
                if let Some(s) = projector.segment(a, b) {
                    painter.line_segment(s, Stroke::new(2.0, colour));
                }
            }
            // A window's front (where the sky light enters the room): its normal, drawn.
            if editor.portals[i].is_window() {
                let c = p.centroid();
                let tip = c + p.normal() * (0.35 * p.area().sqrt());
                if let (Some(a), Some(b)) = (projector.point(c), projector.point(tip)) {
                    painter.arrow(a, b - a, Stroke::new(2.0, colour));
                }
            }
        }
        let light_colour = Color32::from_rgb(255, 170, 60);
        for light in &self.rendered.geometry.lights {
            if let Some(p) = &light.polygon {
                for (a, b) in p.edges() {
                    if let Some(s) = projector.segment(a, b) {
                        painter.line_segment(s, Stroke::new(1.5, light_colour));
                    }
                }
            }
        }
        // A light of any other shape (a bulb, a tube) as its triangles, up to a budget.
        let mut budget = MAX_LIGHT_TRIANGLES_DRAWN;
        for light in self
            .rendered
            .geometry
            .lights
            .iter()
            .filter(|l| l.polygon.is_none())
        {
            for [a, b, c] in light.triangles().take(budget) {
                budget -= 1;
                for (p, q) in [(a, b), (b, c), (c, a)] {
                    if let Some(s) = projector.segment(p, q) {
                        painter.line_segment(s, Stroke::new(0.5, light_colour));
                    }
                }
            }
        }
    }

    /// Volume edges run from a light vertex through a portal vertex and on into the scene;
    /// those of the overlay's portal only, if it shows one.
    fn draw_volumes(
        &self,
        overlay_portal: Option<usize>,
        painter: &egui::Painter,
        projector: &Projector,
    ) {
        let reach = self.rendered.geometry.scale();
        for (j, portal) in self.rendered.portals.iter().enumerate() {
            if overlay_portal.is_some_and(|o| o != j) {
                continue;
            }
            for edge in portal.planes.volume_edges() {
                let dir = (edge.portal_vertex - edge.light_vertex).normalize_or_zero();
                let far = edge.portal_vertex + dir * reach;
                let colour = region_colour(edge.region);
                if let Some(s) = projector.segment(edge.light_vertex, far) {
                    painter.line_segment(s, Stroke::new(1.0, colour));
                }
            }
        }
    }
}

impl PortalViewApp {
    pub(super) fn viewport(&mut self, ui: &mut Ui, commands: &mut Vec<Command>) {
        let available = ui.available_size();
        let scale = self.settings.resolution_scale * ui.ctx().pixels_per_point();
        let size = (
            ((available.x * scale) as u32).max(16),
            ((available.y * scale) as u32).max(16),
        );
        if size != self.requested_size {
            self.requested_size = size;
            commands.push(Command::Restart);
        }
        let (rect, response) = ui.allocate_exact_size(available, Sense::click_and_drag());
        self.image_rect = Some(rect);
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::BLACK);
        let Self {
            current,
            editor,
            gizmo,
            view,
            settings,
            overlay_portal,
            job,
            placing_window,
            context_point,
            ..
        } = self;
        let Some(current) = current else {
            let text = job
                .as_ref()
                .map_or("no scene".into(), |j| format!("{}…", j.what));
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                text,
                egui::FontId::proportional(16.0),
                Color32::GRAY,
            );
            return;
        };
        let uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
        if let Some(texture) = &view.texture {
            painter.image(texture.id(), rect, uv, Color32::WHITE);
        }
        if settings.overlay != OverlayKind::None
            && let Some(texture) = &view.overlay_texture
        {
            painter.image(texture.id(), rect, uv, Color32::WHITE);
        }
        let projector = Projector {
            camera: current.camera,
            rect,
        };
        if settings.show_outlines {
            current.draw_outlines(editor, &painter, &projector);
        }
        if settings.show_volumes {
            current.draw_volumes(*overlay_portal, &painter, &projector);
        }
        let selected = editor.selected.and_then(|i| {
            let polygon = current.portal_polygon(editor, i)?;
            Some((i, PortalFrame::of(&polygon)))
        });
        if let Some((_, frame)) = &selected {
            gizmo.draw(&painter, &projector, frame);
        }

        // Gizmo drags first; otherwise the mouse moves the camera.
        match gizmo.interact(&response, &projector, selected, editor) {
            Some(true) => commands.push(Command::PortalEdited),
            Some(false) => {}
            None => {
                if camera_input(ui, &response, rect, &mut current.camera) {
                    commands.push(Command::Restart);
                }
                if response.double_clicked() {
                    commands.push(Command::ResetCamera);
                }
            }
        }
        // Adding a window portal: a click on the image says where its opening is.
        if *placing_window {
            painter.text(
                rect.center_top() + egui::vec2(0.0, 12.0),
                egui::Align2::CENTER_TOP,
                "Click a window opening to fit a window portal to it (Esc cancels)",
                egui::FontId::proportional(15.0),
                Color32::from_rgb(255, 230, 80),
            );
            if response.hovered() {
                ui.ctx().set_cursor_icon(egui::CursorIcon::Crosshair);
            }
        }
        if *placing_window
            && response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
        {
            let (ndc, aspect) = projector.ndc(pos);
            commands.push(Command::AddWindowAt { ndc, aspect });
        }
        // A right click opens the image's menu, for the point clicked.
        if response.secondary_clicked() {
            *context_point = response.interact_pointer_pos();
        }
        response.context_menu(|ui| {
            if ui
                .button("Add window portal here")
                .on_hover_text(
                    "A window portal fitted to the opening (a hole in a wall) under this point",
                )
                .clicked()
                && let Some(pos) = *context_point
            {
                let (ndc, aspect) = projector.ndc(pos);
                commands.push(Command::AddWindowAt { ndc, aspect });
                ui.close();
            }
        });
        // A click on a portal's outline selects it.
        if response.clicked()
            && !*placing_window
            && let Some(pos) = response.interact_pointer_pos()
            && let Some(i) = current.portal_under(editor, &projector, pos)
        {
            editor.selected = Some(i);
            *overlay_portal = current.rendered_index(i);
        }
        if let Some(pos) = response.hover_pos() {
            inspector(ui, view, current, settings.overlay, (rect, pos));
        }
    }
}

/// Orbit (left drag), pan (right or middle drag) and zoom (scroll); whether the camera moved.
fn camera_input(ui: &Ui, response: &egui::Response, rect: Rect, camera: &mut Camera) -> bool {
    let mut moved = false;
    let delta = response.drag_delta();
    if response.dragged_by(egui::PointerButton::Primary) && delta != egui::Vec2::ZERO {
        camera.orbit(delta.x * 0.01, delta.y * 0.01);
        moved = true;
    }
    if (response.dragged_by(egui::PointerButton::Secondary)
        || response.dragged_by(egui::PointerButton::Middle))
        && delta != egui::Vec2::ZERO
    {
        camera.pan(-delta.x / rect.height(), delta.y / rect.height());
        moved = true;
    }
    if response.hovered() {
        let scroll = ui.input(|i| i.smooth_scroll_delta.y);
        if scroll != 0.0 {
            camera.zoom(scroll * 0.002);
            moved = true;
        }
    }
    moved
}

/// What the hovered pixel shows: radiance, its region for each portal, the technique, the
/// light selection's spread; its swatch has the pixel's colour in the overlay shown (the
/// region's without one).
fn inspector(
    ui: &Ui,
    view: &FrameView,
    current: &Current,
    overlay: OverlayKind,
    (rect, pos): (Rect, Pos2),
) {
    let Some(frame) = &view.frame else {
        return;
    };
    let u = ((pos - rect.min) / rect.size()).clamp(egui::Vec2::ZERO, egui::vec2(0.9999, 0.9999));
    let (x, y) = (
        (u.x * frame.width as f32) as usize,
        (u.y * frame.height as f32) as usize,
    );
    let Some(&radiance) = frame.pixels.get(y * frame.width as usize + x) else {
        return;
    };
    let mut text = format!(
        "pixel {x},{y}\nradiance {:.4} {:.4} {:.4} (luminance {:.4})",
        radiance.x,
        radiance.y,
        radiance.z,
        luminance(radiance)
    );
    if let Some(primary) = &frame.primary
        && primary.width == frame.width
    {
        let i = y * primary.width as usize + x;
        match primary.points.get(i).copied().flatten() {
            Some(p) => {
                text += &format!("\nhit {:.3} {:.3} {:.3}", p.x, p.y, p.z);
                for (j, name) in current.rendered.overlay_portal_names().iter().enumerate() {
                    if let Some(r) = primary.region(i, Some(j)) {
                        text += &format!("\n{name}: {}", r.name());
                    }
                }
                text += &format!(
                    "\nantishadow uses: {}",
                    overlay::technique_name(primary.technique[i], primary.region(i, None))
                );
                if let Some(lights) = primary.spread.get(i).copied().flatten() {
                    text += &format!(
                        "\nlights carrying {:.0}% of picks: {lights}",
                        100.0 * SPREAD_SHARE
                    );
                }
            }
            None => text += "\nno hit",
        }
    }
    let colour = frame
        .primary
        .as_ref()
        .and_then(|p| {
            let i = y * p.width as usize + x;
            match overlay {
                OverlayKind::LightSelection => p
                    .spread
                    .get(i)
                    .copied()
                    .flatten()
                    .map(overlay::spread_colour),
                _ => p.combined.get(i).copied().flatten().map(region_colour),
            }
        })
        .unwrap_or(Color32::GRAY);
    // Anchored by its bottom left, so that a scene with many portals (a line each) grows it
    // upwards, over the image, rather than below it.
    egui::Area::new(egui::Id::unique("inspector"))
        .pivot(egui::Align2::LEFT_BOTTOM)
        .fixed_pos(rect.left_bottom() + egui::vec2(8.0, -8.0))
        .interactable(false)
        .show(ui.ctx(), |ui| {
            egui::Frame::popup(ui.style()).show(ui, |ui| {
                ui.horizontal(|ui| {
                    let (r, _) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), Sense::hover());
                    ui.painter().rect_filled(r, 2.0, colour);
                    ui.label(egui::RichText::new(text).monospace().size(11.0));
                });
            });
        });
}

fn distance_to_segment(p: Pos2, [a, b]: [Pos2; 2]) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_sq().max(1e-6)).clamp(0.0, 1.0);
    (a + ab * t).distance(p)
}

fn inside_convex(points: &[Pos2], p: Pos2) -> bool {
    let n = points.len();
    let side = |k: usize| {
        (points[(k + 1) % n] - points[k]).x * (p - points[k]).y
            - (points[(k + 1) % n] - points[k]).y * (p - points[k]).x
    };
    let first = side(0);
    (1..n).all(|k| side(k) * first >= 0.0)
}
