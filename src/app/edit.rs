//! Portal editing: the portals as the user is shaping them, their poses, undo and redo.

use glam::{Mat4, Quat, Vec3};

use crate::asset::desc::PortalDesc;
use crate::asset::environment::ENVIRONMENT_TARGET;
use crate::camera::Camera;
use crate::sampling::polygon::ConvexPolygon;
use crate::scene::Scene;
use crate::scene::opening::Opening;

/// A portal's placement: `world_from_local = T(center) · R · S · T(-local_center)`, so that
/// moving, turning and resizing all happen about the portal's own centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// The portal's centre in world space.
    pub center: Vec3,
    pub rotation: Quat,
    pub scale: Vec3,
}

/// The centre of a portal's mesh in its local space.
fn local_center(desc: &PortalDesc) -> Vec3 {
    match ConvexPolygon::from_triangles(&desc.local_triangles) {
        Ok(p) => p.centroid(),
        Err(_) => {
            let n = (desc.local_triangles.len() * 3).max(1) as f32;
            desc.local_triangles.iter().flatten().copied().sum::<Vec3>() / n
        }
    }
}

impl Pose {
    pub fn of(desc: &PortalDesc) -> Pose {
        let (scale, rotation, _) = desc.world_from_local.to_scale_rotation_translation();
        Pose {
            center: desc.world_from_local.transform_point3(local_center(desc)),
            rotation,
            scale,
        }
    }

    /// Writes this pose into `desc`'s transform.
    pub fn apply(&self, desc: &mut PortalDesc) {
        desc.world_from_local =
            Mat4::from_scale_rotation_translation(self.scale, self.rotation, self.center)
                * Mat4::from_translation(-local_center(desc));
    }
}

/// The portals being edited, with undo and redo of whole portal lists.
#[derive(Clone, Debug, Default)]
pub struct PortalEditor {
    pub portals: Vec<PortalDesc>,
    pub selected: Option<usize>,
    undo: Vec<Vec<PortalDesc>>,
    redo: Vec<Vec<PortalDesc>>,
    /// Changed since loading or saving.
    pub dirty: bool,
}

impl PortalEditor {
    pub fn new(scene: &Scene) -> Self {
        PortalEditor {
            portals: scene.desc.portals.clone(),
            selected: (!scene.desc.portals.is_empty()).then_some(0),
            ..PortalEditor::default()
        }
    }

    /// Remembers the current portals before an edit (one undo step per gesture).
    pub fn checkpoint(&mut self) {
        self.undo.push(self.portals.clone());
        self.redo.clear();
        self.dirty = true;
    }

    pub fn can_undo(&self) -> bool {
        !self.undo.is_empty()
    }

    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    pub fn undo(&mut self) -> bool {
        let Some(previous) = self.undo.pop() else {
            return false;
        };
        self.redo
            .push(std::mem::replace(&mut self.portals, previous));
        self.clamp_selection();
        self.dirty = true;
        true
    }

    pub fn redo(&mut self) -> bool {
        let Some(next) = self.redo.pop() else {
            return false;
        };
        self.undo.push(std::mem::replace(&mut self.portals, next));
        self.clamp_selection();
        self.dirty = true;
        true
    }

    fn clamp_selection(&mut self) {
        if self.selected.is_some_and(|s| s >= self.portals.len()) {
            self.selected = self.portals.len().checked_sub(1);
        }
    }

    pub fn pose(&self, i: usize) -> Option<Pose> {
        self.portals.get(i).map(Pose::of)
    }

    /// Sets portal `i`'s pose (the caller checkpoints once per gesture).
    pub fn set_pose(&mut self, i: usize, pose: Pose) {
        if let Some(desc) = self.portals.get_mut(i) {
            pose.apply(desc);
            self.dirty = true;
        }
    }

    /// Adds a portal the shape of light `light`, a little in front of its emitting side, and
    /// selects it. A light of any other shape (a bulb, a tube) gets a square below it, as wide
    /// as the light and facing down, the way a lamp hangs.
    pub fn add_for_light(&mut self, scene: &Scene, light: usize) -> Option<usize> {
        let l = scene.geometry.lights.get(light)?;
        let corners: Vec<Vec3> = match l.polygon.as_ref() {
            Some(polygon) => {
                let offset = polygon.normal() * (0.5 * polygon.area().sqrt());
                polygon.vertices().iter().map(|&p| p + offset).collect()
            }
            None => {
                let (lo, hi) = l
                    .corners()
                    .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
                        (lo.min(p), hi.max(p))
                    });
                let half = 0.5 * (hi - lo).max_element().max(1e-6);
                let c = Vec3::new(0.5 * (lo.x + hi.x), lo.y - half, 0.5 * (lo.z + hi.z));
                [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                    .iter()
                    .map(|&(a, b)| c + Vec3::new(a * half, 0.0, b * half))
                    .collect()
            }
        };
        let taken = |name: &str| self.portals.iter().any(|p| p.name == name);
        let name = (1..)
            .map(|k| format!("portal_{}_{k}", l.name))
            .find(|n| !taken(n))
            .unwrap_or_default();
        self.checkpoint();
        self.portals
            .push(PortalDesc::from_polygon(name, l.name.clone(), &corners));
        self.selected = Some(self.portals.len() - 1);
        self.selected
    }

    /// Adds a window portal onto the environment: a 1 m square at the camera's target, its
    /// front facing the camera (the room's side), and selects it.
    pub fn add_window(&mut self, camera: &Camera) -> Option<usize> {
        let n = (camera.eye - camera.target).try_normalize()?;
        let tangent = n
            .cross(camera.up)
            .try_normalize()
            .unwrap_or(n.any_orthonormal_vector());
        let bitangent = n.cross(tangent);
        let c = camera.target;
        let h = 0.5;
        // Counter-clockwise around n: the front faces the camera.
        let corners: Vec<Vec3> = [(-h, -h), (h, -h), (h, h), (-h, h)]
            .into_iter()
            .map(|(a, b)| c + a * tangent + b * bitangent)
            .collect();
        self.push_window(&corners)
    }

    /// Adds a window portal onto the environment filling a fitted opening, its front facing
    /// into the room, and selects it.
    pub fn add_window_in(&mut self, opening: &Opening) -> Option<usize> {
        self.push_window(&opening.corners)
    }

    /// Adds a window portal with these corners (counter-clockwise about its front) and
    /// selects it (one undo step).
    fn push_window(&mut self, corners: &[Vec3]) -> Option<usize> {
        let taken = |name: &str| self.portals.iter().any(|p| p.name == name);
        let name = (1..)
            .map(|k| format!("window_{k}"))
            .find(|n| !taken(n))
            .unwrap_or_default();
        self.checkpoint();
        self.portals.push(PortalDesc::from_polygon(
            name,
            ENVIRONMENT_TARGET.to_owned(),
            corners,
        ));
        self.selected = Some(self.portals.len() - 1);
        self.selected
    }

    /// Turns portal `i`'s front over (what decides a window's side).
    pub fn flip(&mut self, i: usize) -> bool {
        let Some(flipped) = self.portals.get(i).map(PortalDesc::flipped) else {
            return false;
        };
        self.checkpoint();
        self.portals[i] = flipped;
        true
    }

    pub fn delete(&mut self, i: usize) {
        if i < self.portals.len() {
            self.checkpoint();
            self.portals.remove(i);
            self.clamp_selection();
        }
    }

    /// After saving: the file now holds these portals.
    pub fn mark_saved(&mut self) {
        self.dirty = false;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_round_trips_and_undo_restores() {
        let scene = Scene::open("fig8b").unwrap();
        let mut editor = PortalEditor::new(&scene);
        let before = editor.portals.clone();
        let pose = editor.pose(0).unwrap();
        let mut moved = pose;
        moved.center += Vec3::new(0.1, 0.0, 0.2);
        moved.rotation = Quat::from_rotation_y(0.3);
        moved.scale = Vec3::splat(0.8);
        editor.checkpoint();
        editor.set_pose(0, moved);
        let back = editor.pose(0).unwrap();
        assert!(back.center.abs_diff_eq(moved.center, 1e-5));
        assert!(back.scale.abs_diff_eq(moved.scale, 1e-5));
        assert!(back.rotation.abs_diff_eq(moved.rotation, 1e-5));
        assert!(editor.undo());
        assert_eq!(editor.portals, before);
        assert!(editor.redo());
        assert_ne!(editor.portals, before);
    }

    #[test]
    fn added_window_faces_the_camera_and_flips() {
        let scene = Scene::open("window").unwrap();
        let mut editor = PortalEditor::new(&scene);
        let camera = scene.camera;
        let i = editor.add_window(&camera).unwrap();
        let (rendered, errors) = scene.with_portals_lenient(editor.portals.clone());
        assert!(errors.is_empty(), "{errors:?}");
        let window = rendered.windows.iter().find(|w| w.desc_index == i).unwrap();
        assert!(window.in_front(camera.eye));
        assert!(editor.flip(i));
        let (rendered, _) = scene.with_portals_lenient(editor.portals.clone());
        let window = rendered.windows.iter().find(|w| w.desc_index == i).unwrap();
        assert!(!window.in_front(camera.eye));
        assert!(editor.undo());
        assert_eq!(
            editor.portals[i].local_triangles,
            editor.portals[i].flipped().flipped().local_triangles
        );
    }

    #[test]
    fn added_portal_is_valid() {
        let scene = Scene::open("fig8a").unwrap();
        let mut editor = PortalEditor::new(&scene);
        editor.add_for_light(&scene, 0).unwrap();
        let (_, errors) = scene.with_portals_lenient(editor.portals.clone());
        assert!(errors.is_empty(), "{errors:?}");
    }
}
