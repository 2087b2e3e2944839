//! Opening and saving files in the viewer as a user does, driven by egui_kittest with software
//! Vulkan: File → Open glTF… shows the in-app file dialog and the chosen file loads; the dialog
//! lists folders and glTF files only, and Cancel leaves everything as it was; a path
//! typed into the menu bar's field opens with Enter; a broken file's error names it in the
//! side panel while the current scene stays, and a first scene that fails leaves the lampshade
//! with its error; File → Save as .glb… saves through the dialog.

use egui::accesskit::Role;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::Vec3;
use portalview::app::PortalViewApp;
use portalview::scene::Scene;
use std::path::{Path, PathBuf};

mod ui_common;

use ui_common::{harness_with, serial, step_until};

fn asset(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(name)
}

/// A fresh, empty folder for this test's files.
fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("portalview-ui-files-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Whether the scene on screen came from `path`, and nothing is loading.
fn shows_file(app: &PortalViewApp, path: &Path) -> bool {
    !app.is_busy() && app.scene().and_then(|s| s.source.as_deref()) == Some(path)
}

/// Types `text` into the menu bar's path field and presses Enter.
fn type_path(h: &mut Harness<'static, PortalViewApp>, text: &str) {
    h.get_by_role_and_label(Role::TextInput, "Path:").click();
    h.run_steps(2);
    h.get_by_role_and_label(Role::TextInput, "Path:")
        .type_text(text);
    h.step();
    h.key_press(egui::Key::Enter);
    h.run_steps(2);
}

#[test]
fn the_open_dialog_loads_the_chosen_file() {
    let _serial = serial();
    // The dialog starts in the folder of the newest recent file: the assets.
    let mut h = harness_with("lampshade", |app| {
        app.settings.recent = vec![asset("fig8a.glb").display().to_string()];
    });
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Open glTF…").click();
    h.run_steps(3);
    // The dialog lists the glTF files of the folder and nothing else.
    assert!(
        h.query_by_label_contains("Open glTF scene").is_some(),
        "no dialog"
    );
    assert!(h.query_by_label("🗋 fig8b.glb").is_some());
    assert!(h.query_by_label_contains(".md").is_none());
    h.get_by_label("🗋 fig8b.glb").click();
    h.run_steps(2);
    h.get_by_role_and_label(Role::Button, "Open").click();
    h.run_steps(2);
    let path = asset("fig8b.glb");
    step_until(&mut h, "fig8b from the dialog", |a| shows_file(a, &path));
    assert!(
        h.query_by_label_contains("Open glTF scene").is_none(),
        "the dialog stayed"
    );
    assert_eq!(h.state().scene().unwrap().name, "fig8b");
    assert_eq!(h.state().settings.recent[0], path.display().to_string());
    // The render follows the new scene.
    step_until(&mut h, "a frame of fig8b", |a| a.frame().is_some());
}

#[test]
fn the_dialog_lists_folders_and_gltf_files_only_and_cancels() {
    let _serial = serial();
    let dir = temp_dir("listing");
    for name in ["a.glb", "b.GLTF", "notes.txt", "image.exr"] {
        std::fs::write(dir.join(name), b"").unwrap();
    }
    std::fs::create_dir(dir.join("sub")).unwrap();
    let recent = dir.join("a.glb").display().to_string();
    let mut h = harness_with("fig8a", move |app| app.settings.recent = vec![recent]);
    h.get_by_role_and_label(Role::Button, "Browse…").click();
    h.run_steps(3);
    for shown in ["🗋 a.glb", "🗋 b.GLTF", "🗀 sub"] {
        assert!(h.query_by_label(shown).is_some(), "{shown} not listed");
    }
    for hidden in ["notes.txt", "image.exr"] {
        assert!(
            h.query_by_label_contains(hidden).is_none(),
            "{hidden} listed"
        );
    }
    h.get_by_role_and_label(Role::Button, "Cancel").click();
    h.run_steps(2);
    assert!(h.query_by_label_contains("Open glTF scene").is_none());
    assert!(!h.state().is_busy());
    assert_eq!(h.state().scene().unwrap().name, "fig8a");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_typed_path_opens_with_enter() {
    let _serial = serial();
    let mut h = harness_with("lampshade", |_| {});
    let path = asset("fig8c.glb");
    type_path(&mut h, &path.display().to_string());
    step_until(&mut h, "fig8c from the path field", |a| {
        shows_file(a, &path)
    });
    assert_eq!(h.state().message(), None);
}

#[test]
fn a_broken_file_reports_its_error_and_keeps_the_scene() {
    let _serial = serial();
    let dir = temp_dir("broken");
    let broken = dir.join("broken.glb");
    std::fs::write(&broken, b"glTF not really").unwrap();
    let mut h = harness_with("fig8a", |_| {});
    type_path(&mut h, &broken.display().to_string());
    step_until(&mut h, "the load to fail", |a| !a.is_busy());
    let message = h.state().message().unwrap().to_owned();
    assert!(message.contains(&broken.display().to_string()), "{message}");
    // Shown in the side panel, and the scene on screen is still fig8a.
    h.run_steps(2);
    assert!(h.query_by_label_contains("broken.glb").is_some());
    let scene = h.state().scene().unwrap();
    assert_eq!(scene.name, "fig8a");
    assert!(scene.source.is_none());
    // A file that is not there is reported too.
    let missing = dir.join("missing.gltf");
    type_path(&mut h, &missing.display().to_string());
    step_until(&mut h, "the missing file's error", |a| {
        !a.is_busy() && a.message().is_some_and(|m| m.contains("missing.gltf"))
    });
    assert_eq!(h.state().scene().unwrap().name, "fig8a");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn save_as_glb_goes_through_the_dialog() {
    let _serial = serial();
    let dir = temp_dir("save-as");
    let target = dir.join("moved.glb");
    let mut h = harness_with("fig8b", |_| {});
    let app = h.state_mut();
    let mut pose = app.editor.pose(0).unwrap();
    app.editor.checkpoint();
    pose.center += Vec3::new(0.1, 0.0, 0.0);
    app.editor.set_pose(0, pose);
    app.apply_portal_edit();
    let edited = app.editor.portals[0].world_triangles();
    h.get_by_label("File").click();
    h.run_steps(2);
    h.get_by_label("Save as .glb…").click();
    h.run_steps(3);
    // The dialog proposes the scene's name; type a full path instead, and save.
    h.query_all_by(|n| n.role() == Role::TextInput && n.value().as_deref() == Some("fig8b.glb"))
        .next()
        .expect("the dialog's file name field")
        .set_text_value_accesskit(&target.display().to_string());
    h.run_steps(2);
    h.get_by_role_and_label(Role::Button, "Save").click();
    h.run_steps(2);
    step_until(&mut h, "saved as", |a| shows_file(a, &target));
    assert!(!h.state().editor.dirty);
    let saved = Scene::load(&target).unwrap();
    for (a, b) in saved.desc.portals[0]
        .world_triangles()
        .iter()
        .flatten()
        .zip(edited.iter().flatten())
    {
        assert!(a.abs_diff_eq(*b, 1e-4), "{a} vs {b}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_first_scene_that_fails_falls_back_to_the_lampshade_with_its_error() {
    let _serial = serial();
    let dir = temp_dir("first");
    let broken = dir.join("first.gltf");
    std::fs::write(&broken, b"{ not json").unwrap();
    let mut h = harness_with(&broken.display().to_string(), |_| {});
    assert_eq!(h.state().scene().unwrap().name, "lampshade");
    let message = h.state().message().unwrap().to_owned();
    assert!(message.contains(&broken.display().to_string()), "{message}");
    h.run_steps(2);
    assert!(h.query_by_label_contains("first.gltf").is_some());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_unread_extension_is_a_warning_in_the_side_panel() {
    let _serial = serial();
    let dir = temp_dir("unread");
    // One triangle, its three positions (36 bytes) in a data URI, and an extension nobody reads.
    let positions: Vec<u8> = [0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["EXT_made_up_for_this_test"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "Triangle", "mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 0.0]}],
        "bufferViews": [{"buffer": 0, "byteLength": 36}],
        "buffers": [{"byteLength": 36, "uri": format!(
            "data:application/octet-stream;base64,{}", base64::encode(&positions))}]
    });
    let path = dir.join("made-up.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let mut h = harness_with(&path.display().to_string(), |_| {});
    assert!(
        shows_file(h.state(), &path),
        "the file loads despite the extension"
    );
    let message = h.state().message().unwrap_or_default().to_owned();
    assert!(
        message.contains("made-up.gltf") && message.contains("EXT_made_up_for_this_test"),
        "{message}"
    );
    h.run_steps(2);
    assert!(
        h.query_by_label_contains("EXT_made_up_for_this_test")
            .is_some()
    );
    let _ = std::fs::remove_dir_all(&dir);
}
