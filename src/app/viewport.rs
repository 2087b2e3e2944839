//! The image area: the render and its overlay, camera controls, portal and light outlines,
//! antishadow volume edges, the pixel inspector, and the portal gizmo. Also the portal panel's
//! numeric fields.

use egui::{Color32, Pos2, Rect, Sense, Stroke, Ui};
use glam::{Quat, Vec2, Vec3};

use super::edit::Pose;
use super::overlay::region_colour;
use super::{Command, PortalViewApp};
use crate::light::antishadow::Region;
use crate::light::area::luminance;
use crate::sampling::polygon::ConvexPolygon;

/// The gizmo's handles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Handle {
    /// Slide in the portal's plane.
    Move,
    /// Move along the portal's normal.
    Lift,
    /// Resize about the centre.
    Scale,
    /// Turn about the normal.
    Spin,
    /// Tilt about the portal's first edge.
    Tilt,
}

/// A drag in progress.
#[derive(Clone, Copy, Debug)]
struct Drag {
    handle: Handle,
    portal: usize,
    start: Pose,
    start_mouse: Pos2,
    /// Where the mouse ray met the portal plane when the drag began (Move).
    start_hit: Option<Vec3>,
    frame: PortalFrame,
}

#[derive(Default)]
pub struct Gizmo {
    drag: Option<Drag>,
}

/// A portal's axes in world space, for its handles.
#[derive(Clone, Copy, Debug)]
struct PortalFrame {
    center: Vec3,
    /// Normal, first-edge tangent and their cross product.
    n: Vec3,
    t: Vec3,
    b: Vec3,
    /// Handle distance from the centre.
    r: f32,
}

impl PortalFrame {
    fn of(polygon: &ConvexPolygon) -> Self {
        let v = polygon.vertices();
        let n = polygon.normal();
        let t = (v[1] - v[0]).normalize_or(n.any_orthonormal_vector());
        PortalFrame {
            center: polygon.centroid(),
            n,
            t,
            b: n.cross(t),
            r: 0.6 * polygon.area().sqrt(),
        }
    }

    fn handle_point(&self, h: Handle) -> Vec3 {
        match h {
            Handle::Move => self.center,
            Handle::Lift => self.center + self.n * self.r,
            Handle::Scale => self.center + (self.t + self.b) * (0.75 * self.r),
            Handle::Spin => self.center + self.t * (1.25 * self.r),
            Handle::Tilt => self.center + self.b * (1.25 * self.r),
        }
    }
}

const HANDLES: [Handle; 5] = [
    Handle::Move,
    Handle::Lift,
    Handle::Scale,
    Handle::Spin,
    Handle::Tilt,
];

/// Maps world points to screen points through the camera, for an image drawn in `rect`.
struct Projector {
    camera: crate::camera::Camera,
    rect: Rect,
}

impl Projector {
    fn aspect(&self) -> f32 {
        self.rect.width() / self.rect.height().max(1.0)
    }
    fn point(&self, p: Vec3) -> Option<Pos2> {
        let ndc = self.camera.project(p, self.aspect())?;
        Some(self.rect.min + egui::vec2(ndc.x * self.rect.width(), ndc.y * self.rect.height()))
    }
    fn segment(&self, a: Vec3, b: Vec3) -> Option<[Pos2; 2]> {
        let (na, nb) = self.camera.project_segment(a, b, self.aspect())?;
        let to =
            |n: Vec2| self.rect.min + egui::vec2(n.x * self.rect.width(), n.y * self.rect.height());
        Some([to(na), to(nb)])
    }
    /// The camera ray through a screen point.
    fn ray(&self, pos: Pos2) -> (Vec3, Vec3) {
        let ndc = Vec2::new(
            (pos.x - self.rect.min.x) / self.rect.width(),
            (pos.y - self.rect.min.y) / self.rect.height(),
        );
        self.camera.ray(ndc, self.aspect())
    }
}

fn distance_to_segment(p: Pos2, [a, b]: [Pos2; 2]) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_sq().max(1e-6)).clamp(0.0, 1.0);
    (a + ab * t).distance(p)
}

impl PortalViewApp {
    /// The world polygon of the editor's portal `i` (the rendered portal's, oriented, when
    /// valid; else the raw mesh), if it forms one.
    fn portal_polygon(&self, i: usize) -> Option<ConvexPolygon> {
        if let Some(p) = self.rendered.portals.iter().find(|p| p.desc_index == i) {
            return Some(p.polygon.clone());
        }
        ConvexPolygon::from_triangles(&self.editor.portals.get(i)?.world_triangles()).ok()
    }

    pub(super) fn viewport(&mut self, ui: &mut Ui, commands: &mut Vec<Command>) {
        let available = ui.available_size();
        let ppp = ui.ctx().pixels_per_point();
        let scale = self.settings.resolution_scale * ppp;
        let size = (
            ((available.x * scale) as u32).max(16),
            ((available.y * scale) as u32).max(16),
        );
        if size != self.requested_size {
            self.requested_size = size;
            commands.push(Command::Restart);
        }
        let (rect, response) = ui.allocate_exact_size(available, Sense::click_and_drag());
        let uv = Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0));
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 0.0, Color32::BLACK);
        if let Some(texture) = &self.texture {
            painter.image(texture.id(), rect, uv, Color32::WHITE);
        }
        if self.settings.overlay != super::OverlayKind::None
            && let Some(texture) = &self.overlay_texture
        {
            painter.image(texture.id(), rect, uv, Color32::WHITE);
        }
        let projector = Projector {
            camera: self.camera,
            rect,
        };
        if self.settings.show_outlines {
            self.draw_outlines(&painter, &projector);
        }
        if self.settings.show_volumes {
            self.draw_volumes(&painter, &projector);
        }
        let selected_frame = self
            .editor
            .selected
            .and_then(|i| self.portal_polygon(i))
            .map(|p| PortalFrame::of(&p));
        if let Some(frame) = selected_frame {
            draw_gizmo(
                &painter,
                &projector,
                &frame,
                self.gizmo.drag.map(|d| d.handle),
            );
        }

        // Gizmo drags first; otherwise the mouse moves the camera.
        let pointer = response.interact_pointer_pos();
        if response.drag_started_by(egui::PointerButton::Primary)
            && let (Some(pos), Some(frame), Some(i)) =
                (pointer, selected_frame, self.editor.selected)
            && let Some(handle) = pick_handle(&projector, &frame, pos)
            && let Some(start) = self.editor.pose(i)
        {
            self.editor.checkpoint();
            let (o, d) = projector.ray(pos);
            let plane = crate::sampling::polygon::Plane::from_point_normal(frame.center, frame.n);
            self.gizmo.drag = Some(Drag {
                handle,
                portal: i,
                start,
                start_mouse: pos,
                start_hit: plane.intersect(o, d).map(|t| o + t * d),
                frame,
            });
        }
        if let Some(drag) = self.gizmo.drag {
            if response.dragged()
                && let Some(pos) = pointer
                && let Some(pose) = drag_pose(&drag, &projector, pos)
            {
                self.editor.set_pose(drag.portal, pose);
                commands.push(Command::PortalEdited);
            }
            if !response.dragged() {
                self.gizmo.drag = None;
            }
        } else {
            let delta = response.drag_delta();
            if response.dragged_by(egui::PointerButton::Primary) && delta != egui::Vec2::ZERO {
                self.camera.orbit(delta.x * 0.01, delta.y * 0.01);
                commands.push(Command::Restart);
            }
            if (response.dragged_by(egui::PointerButton::Secondary)
                || response.dragged_by(egui::PointerButton::Middle))
                && delta != egui::Vec2::ZERO
            {
                self.camera
                    .pan(-delta.x / rect.height(), delta.y / rect.height());
                commands.push(Command::Restart);
            }
            if response.hovered() {
                let scroll = ui.input(|i| i.smooth_scroll_delta.y);
                if scroll != 0.0 {
                    self.camera.zoom(scroll * 0.002);
                    commands.push(Command::Restart);
                }
            }
            if response.double_clicked() {
                self.camera = self.scene.camera;
                commands.push(Command::Restart);
            }
        }
        // A click on a portal's outline selects it.
        if response.clicked()
            && let Some(pos) = response.interact_pointer_pos()
            && let Some(i) = self.portal_under(&projector, pos)
        {
            self.editor.selected = Some(i);
            self.overlay_portal = self.rendered.portals.iter().position(|p| p.desc_index == i);
        }
        if let Some(pos) = response.hover_pos() {
            self.inspector(ui, rect, pos);
        }
    }

    /// The editor index of the portal whose outline or inside is under `pos`.
    fn portal_under(&self, projector: &Projector, pos: Pos2) -> Option<usize> {
        (0..self.editor.portals.len()).find(|&i| {
            self.portal_polygon(i).is_some_and(|p| {
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

    fn draw_outlines(&self, painter: &egui::Painter, projector: &Projector) {
        for (i, _) in self.editor.portals.iter().enumerate() {
            let Some(p) = self.portal_polygon(i) else {
                continue;
            };
            let broken = self.portal_errors.iter().any(|(e, _)| *e == i);
            let colour = if broken {
                Color32::RED
            } else if self.editor.selected == Some(i) {
                Color32::from_rgb(255, 230, 80)
            } else {
                Color32::from_rgb(80, 220, 255)
            };
            for (a, b) in p.edges() {
                if let Some(s) = projector.segment(a, b) {
                    painter.line_segment(s, Stroke::new(2.0, colour));
                }
            }
        }
        for light in &self.rendered.geometry.lights {
            if let Some(p) = &light.polygon {
                for (a, b) in p.edges() {
                    if let Some(s) = projector.segment(a, b) {
                        painter.line_segment(s, Stroke::new(1.5, Color32::from_rgb(255, 170, 60)));
                    }
                }
            }
        }
    }

    /// Volume edges run from a light vertex through a portal vertex and on into the scene.
    fn draw_volumes(&self, painter: &egui::Painter, projector: &Projector) {
        let reach = self.rendered.geometry.scale();
        for portal in &self.rendered.portals {
            if self
                .overlay_portal
                .is_some_and(|j| self.rendered.portals[j].desc_index != portal.desc_index)
            {
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

    /// What the hovered pixel shows: radiance, its region for each portal, the technique.
    fn inspector(&self, ui: &Ui, rect: Rect, pos: Pos2) {
        let Some(frame) = &self.frame else {
            return;
        };
        let u =
            ((pos - rect.min) / rect.size()).clamp(egui::Vec2::ZERO, egui::vec2(0.9999, 0.9999));
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
                    for (j, portal) in self.rendered.portals.iter().enumerate() {
                        if let Some(r) = primary.region(i, Some(j)) {
                            text += &format!("\n{}: {}", portal.name, r.name());
                        }
                    }
                    let technique = primary.technique[i];
                    text += &format!(
                        "\nantishadow uses: {}",
                        technique.map_or("light alone", |t| t.name())
                    );
                }
                None => text += "\nno hit",
            }
        }
        let colour = frame
            .primary
            .as_ref()
            .and_then(|p| p.combined.get(y * p.width as usize + x).copied().flatten())
            .map_or(Color32::GRAY, |r: Region| region_colour(r));
        egui::Area::new(egui::Id::unique("inspector"))
            .fixed_pos(rect.left_bottom() + egui::vec2(8.0, -110.0))
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

    /// The portal list and the selected portal's fields.
    pub(super) fn portal_panel(&mut self, ui: &mut Ui, commands: &mut Vec<Command>) {
        let names: Vec<String> = self.editor.portals.iter().map(|p| p.name.clone()).collect();
        for (i, name) in names.iter().enumerate() {
            let broken = self.portal_errors.iter().find(|(e, _)| *e == i);
            let label = if broken.is_some() {
                format!("(!) {name}")
            } else {
                name.clone()
            };
            if ui
                .selectable_label(self.editor.selected == Some(i), label)
                .clicked()
            {
                self.editor.selected = Some(i);
                self.overlay_portal = self.rendered.portals.iter().position(|p| p.desc_index == i);
            }
        }
        for (i, message) in &self.portal_errors {
            ui.colored_label(
                Color32::from_rgb(255, 160, 60),
                format!("portal {i}: {message}"),
            );
        }
        let lights: Vec<(usize, String)> = self
            .scene
            .geometry
            .lights
            .iter()
            .enumerate()
            .filter(|(_, l)| l.polygon.is_some())
            .map(|(i, l)| (i, l.name.clone()))
            .collect();
        ui.horizontal(|ui| {
            for (i, name) in &lights {
                if ui.button(format!("Add portal for {name}")).clicked() {
                    commands.push(Command::AddPortal(*i));
                }
            }
        });
        let Some(i) = self
            .editor
            .selected
            .filter(|&i| i < self.editor.portals.len())
        else {
            ui.label("no portal selected");
            return;
        };
        let Some(mut pose) = self.editor.pose(i) else {
            return;
        };
        let before = pose;
        let (mut ex, mut ey, mut ez) = pose.rotation.to_euler(glam::EulerRot::XYZ);
        let (ex0, ey0, ez0) = (ex, ey, ez);
        let mut gesture = false;
        let mut alpha = self.editor.portals[i].alpha;
        egui::Grid::new("portal fields")
            .num_columns(2)
            .show(ui, |ui| {
                ui.label("centre");
                ui.horizontal(|ui| {
                    for (v, axis) in [
                        (&mut pose.center.x, "x"),
                        (&mut pose.center.y, "y"),
                        (&mut pose.center.z, "z"),
                    ] {
                        let r = ui.add(
                            egui::DragValue::new(v)
                                .speed(0.01)
                                .prefix(format!("{axis} ")),
                        );
                        gesture |= r.drag_started() || r.gained_focus();
                    }
                });
                ui.end_row();
                ui.label("rotation °");
                ui.horizontal(|ui| {
                    for (v, axis) in [(&mut ex, "x"), (&mut ey, "y"), (&mut ez, "z")] {
                        let mut deg = v.to_degrees();
                        let r = ui.add(
                            egui::DragValue::new(&mut deg)
                                .speed(0.5)
                                .prefix(format!("{axis} ")),
                        );
                        gesture |= r.drag_started() || r.gained_focus();
                        *v = deg.to_radians();
                    }
                });
                ui.end_row();
                let label = ui.label("scale");
                let mut s = pose.scale.max_element();
                let r = ui
                    .add(egui::DragValue::new(&mut s).speed(0.01).range(0.01..=100.0))
                    .labelled_by(label.id);
                gesture |= r.drag_started() || r.gained_focus();
                if r.changed() {
                    pose.scale *= s / pose.scale.max_element().max(1e-6);
                }
                ui.end_row();
                let label = ui.label("alpha");
                let r = ui
                    .add(egui::Slider::new(&mut alpha, 0.0..=1.0))
                    .labelled_by(label.id);
                gesture |= r.drag_started() || r.gained_focus();
                ui.end_row();
            });
        if (ex, ey, ez) != (ex0, ey0, ez0) {
            pose.rotation = Quat::from_euler(glam::EulerRot::XYZ, ex, ey, ez);
        }
        if gesture {
            self.editor.checkpoint();
        }
        if pose != before || alpha != self.editor.portals[i].alpha {
            self.editor.set_pose(i, pose);
            self.editor.portals[i].alpha = alpha;
            commands.push(Command::PortalEdited);
        }
        if ui.button("Delete portal").clicked() {
            commands.push(Command::DeletePortal(i));
        }
        if self.editor.dirty {
            ui.label(if self.scene.source.is_some() {
                "unsaved changes (File > Save portals)"
            } else {
                "unsaved changes (File > Save as .glb…)"
            });
        }
    }
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

fn draw_gizmo(
    painter: &egui::Painter,
    projector: &Projector,
    frame: &PortalFrame,
    active: Option<Handle>,
) {
    let Some(c) = projector.point(frame.center) else {
        return;
    };
    let colour = |h: Handle| {
        if active == Some(h) {
            Color32::WHITE
        } else {
            match h {
                Handle::Move => Color32::from_rgb(255, 230, 80),
                Handle::Lift => Color32::from_rgb(80, 160, 255),
                Handle::Scale => Color32::from_rgb(120, 255, 120),
                Handle::Spin => Color32::from_rgb(255, 120, 220),
                Handle::Tilt => Color32::from_rgb(255, 150, 60),
            }
        }
    };
    // The spin ring in the portal's plane.
    let ring: Vec<Pos2> = (0..=48)
        .filter_map(|k| {
            let a = std::f32::consts::TAU * k as f32 / 48.0;
            projector
                .point(frame.center + (frame.t * a.cos() + frame.b * a.sin()) * (1.25 * frame.r))
        })
        .collect();
    painter.add(egui::Shape::line(
        ring,
        Stroke::new(1.0, colour(Handle::Spin)),
    ));
    for h in HANDLES {
        let Some(p) = projector.point(frame.handle_point(h)) else {
            continue;
        };
        if h != Handle::Move {
            painter.line_segment([c, p], Stroke::new(1.5, colour(h)));
        }
        match h {
            Handle::Scale => {
                painter.rect_filled(
                    Rect::from_center_size(p, egui::vec2(10.0, 10.0)),
                    0.0,
                    colour(h),
                );
            }
            _ => {
                painter.circle_filled(p, 6.0, colour(h));
            }
        }
    }
}

/// The handle within reach of `pos`, nearest first.
fn pick_handle(projector: &Projector, frame: &PortalFrame, pos: Pos2) -> Option<Handle> {
    HANDLES
        .into_iter()
        .filter_map(|h| Some((h, projector.point(frame.handle_point(h))?.distance(pos))))
        .filter(|(_, d)| *d < 10.0)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(h, _)| h)
}

/// The pose a drag has reached with the mouse at `pos`.
fn drag_pose(drag: &Drag, projector: &Projector, pos: Pos2) -> Option<Pose> {
    let f = &drag.frame;
    let mut pose = drag.start;
    let c = projector.point(f.center)?;
    match drag.handle {
        Handle::Move => {
            let plane = crate::sampling::polygon::Plane::from_point_normal(f.center, f.n);
            let (o, d) = projector.ray(pos);
            let hit = o + d * plane.intersect(o, d)?;
            pose.center = drag.start.center + (hit - drag.start_hit?);
        }
        Handle::Lift => {
            let s = projector.point(f.handle_point(Handle::Lift))? - c;
            let amount = (pos - drag.start_mouse).dot(s) / s.length_sq().max(1.0);
            pose.center = drag.start.center + f.n * (f.r * amount);
        }
        Handle::Scale => {
            let ratio = (pos - c).length() / (drag.start_mouse - c).length().max(1.0);
            pose.scale = drag.start.scale * ratio.clamp(0.05, 20.0);
        }
        Handle::Spin => {
            let angle = |p: Pos2| (-(p.y - c.y)).atan2(p.x - c.x);
            let facing = f.n.dot(projector.camera.eye - f.center).signum();
            let turn = (angle(pos) - angle(drag.start_mouse)) * facing;
            pose.rotation = Quat::from_axis_angle(f.n, turn) * drag.start.rotation;
        }
        Handle::Tilt => {
            let s = projector.point(f.center + f.n * (1.25 * f.r))? - c;
            let amount = (pos - drag.start_mouse).dot(s) / s.length_sq().max(1.0);
            pose.rotation = Quat::from_axis_angle(f.t, amount.atan()) * drag.start.rotation;
        }
    }
    Some(pose)
}
