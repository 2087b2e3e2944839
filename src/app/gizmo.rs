//! The portal gizmo drawn over the image: five handles (move in the plane, lift along the
//! normal, scale, spin about the normal, tilt), picking them and turning drags into poses.

use egui::{Color32, Pos2, Rect, Response, Stroke};
use glam::{Quat, Vec3};

use super::edit::{PortalEditor, Pose};
use super::viewport::Projector;
use crate::sampling::polygon::{ConvexPolygon, Plane};

/// The gizmo's handles.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Handle {
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

const HANDLES: [Handle; 5] = [
    Handle::Move,
    Handle::Lift,
    Handle::Scale,
    Handle::Spin,
    Handle::Tilt,
];

/// A portal's axes in world space, for its handles.
#[derive(Clone, Copy, Debug)]
pub(super) struct PortalFrame {
    center: Vec3,
    /// Normal, first-edge tangent and their cross product.
    n: Vec3,
    t: Vec3,
    b: Vec3,
    /// Handle distance from the centre.
    r: f32,
}

impl PortalFrame {
    pub fn of(polygon: &ConvexPolygon) -> Self {
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
pub(super) struct Gizmo {
    drag: Option<Drag>,
}

impl Gizmo {
    /// Starts a drag on a handle of the selected portal (`selected`: its editor index and
    /// frame), or moves the portal being dragged. `None` when the gizmo is not dragging (the
    /// pointer is the camera's), else whether the portal changed.
    pub fn interact(
        &mut self,
        response: &Response,
        projector: &Projector,
        selected: Option<(usize, PortalFrame)>,
        editor: &mut PortalEditor,
    ) -> Option<bool> {
        let pointer = response.interact_pointer_pos();
        if response.drag_started_by(egui::PointerButton::Primary)
            && let (Some(pos), Some((i, frame))) = (pointer, selected)
            && let Some(handle) = pick_handle(projector, &frame, pos)
            && let Some(start) = editor.pose(i)
        {
            editor.checkpoint();
            let (o, d) = projector.ray(pos);
            let plane = Plane::from_point_normal(frame.center, frame.n);
            self.drag = Some(Drag {
                handle,
                portal: i,
                start,
                start_mouse: pos,
                start_hit: plane.intersect(o, d).map(|t| o + t * d),
                frame,
            });
        }
        let drag = self.drag?;
        if !response.dragged() {
            self.drag = None;
            return Some(false);
        }
        let Some(pose) = pointer.and_then(|pos| drag_pose(&drag, projector, pos)) else {
            return Some(false);
        };
        editor.set_pose(drag.portal, pose);
        Some(true)
    }

    pub fn draw(&self, painter: &egui::Painter, projector: &Projector, frame: &PortalFrame) {
        let Some(c) = projector.point(frame.center) else {
            return;
        };
        let active = self.drag.map(|d| d.handle);
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
                projector.point(
                    frame.center + (frame.t * a.cos() + frame.b * a.sin()) * (1.25 * frame.r),
                )
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
            let plane = Plane::from_point_normal(f.center, f.n);
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
