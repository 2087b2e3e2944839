//! *Add window portal* fits a rectangle to the opening under the mouse: on the built-in
//! `window` and `windows2` rooms, pointing at a window from the scene's camera gives the
//! modelled opening within a millimetre or two, facing into the room; pointing at a plain wall
//! gives none (the viewer then falls back to a default square and says so).

use glam::{Vec2, Vec3};
use portalview::camera::Camera;
use portalview::sampling::polygon::ConvexPolygon;
use portalview::scene::Scene;
use portalview::scene::opening::{Opening, fit_opening};

/// How far a fitted corner may be from the modelled one (the march is bisected to far less;
/// this allows for the wall's seams).
const TOLERANCE: f32 = 2e-3;

/// The modelled opening of the scene's window portal `name` (each built-in window's portal
/// fills its opening).
fn opening_polygon(scene: &Scene, name: &str) -> ConvexPolygon {
    let portal = scene.desc.portals.iter().find(|p| p.name == name).unwrap();
    ConvexPolygon::from_triangles(&portal.world_triangles()).unwrap()
}

/// The image point of `p` through `camera`, at the camera's own aspect.
fn pixel_of(camera: &Camera, p: Vec3) -> Vec2 {
    let ndc = camera.project(p, camera.aspect).unwrap();
    assert!(
        ndc.cmpge(Vec2::ZERO).all() && ndc.cmple(Vec2::ONE).all(),
        "{ndc} off screen"
    );
    ndc
}

/// Every corner of `fit` is within the tolerance of one of `expected`, and the other way.
fn assert_same_corners(fit: &Opening, expected: &[Vec3]) {
    assert_eq!(expected.len(), 4);
    for c in &fit.corners {
        let d = expected
            .iter()
            .map(|e| e.distance(*c))
            .fold(f32::MAX, f32::min);
        assert!(
            d < TOLERANCE,
            "fitted corner {c} is {d} m from {expected:?}"
        );
    }
    for e in expected {
        let d = fit
            .corners
            .iter()
            .map(|c| c.distance(*e))
            .fold(f32::MAX, f32::min);
        assert!(
            d < TOLERANCE,
            "modelled corner {e} is {d} m from {:?}",
            fit.corners
        );
    }
}

/// The fitted portal is a valid window of the scene, in front of (facing) the camera.
fn assert_faces_camera(scene: &Scene, fit: &Opening, eye: Vec3) {
    let desc = portalview::asset::desc::PortalDesc::from_polygon(
        "fitted".into(),
        portalview::asset::environment::ENVIRONMENT_TARGET.into(),
        &fit.corners,
    );
    let polygon = ConvexPolygon::from_triangles(&desc.world_triangles()).unwrap();
    assert!(
        polygon.normal().dot(fit.normal) > 0.999,
        "winding against the normal"
    );
    assert!(
        fit.normal.dot(eye - fit.corners[0]) > 0.0,
        "faces away from the camera"
    );
    let with = scene.with_portals(vec![desc]).unwrap();
    assert!(with.windows[0].in_front(eye));
}

#[test]
fn window_is_fitted_from_the_scene_camera() {
    let scene = Scene::open("window").unwrap();
    let camera = scene.camera;
    let opening = opening_polygon(&scene, "window_north");
    // At the window's centre, and near one corner: the same rectangle.
    let centre = opening.centroid();
    for p in [centre, centre + 0.8 * (opening.vertices()[0] - centre)] {
        let fit = fit_opening(&scene, &camera, pixel_of(&camera, p), camera.aspect)
            .unwrap_or_else(|| panic!("no opening found at {p}"));
        assert_same_corners(&fit, opening.vertices());
        assert!(fit.normal.abs_diff_eq(Vec3::Z, 1e-4), "{}", fit.normal);
        assert!((fit.size - Vec2::new(1.6, 1.3)).abs().max_element() < TOLERANCE);
        assert_faces_camera(&scene, &fit, camera.eye);
    }
}

#[test]
fn windows2_north_and_hexagon_are_fitted() {
    let scene = Scene::open("windows2").unwrap();
    let camera = scene.camera;
    let north = opening_polygon(&scene, "window_north");
    let fit = fit_opening(
        &scene,
        &camera,
        pixel_of(&camera, north.centroid()),
        camera.aspect,
    )
    .unwrap();
    assert_same_corners(&fit, north.vertices());
    assert_faces_camera(&scene, &fit, camera.eye);

    // The hexagon in the east wall, seen from the west of the room: the rectangle is its
    // bounding box in the wall (a portal that covers the whole opening).
    let hexagon = opening_polygon(&scene, "window_east");
    let c = hexagon.centroid();
    let facing = Camera {
        eye: Vec3::new(-1.5, 1.2, -0.6),
        target: c,
        ..camera
    };
    // Off the centre, towards a vertex: the scans still find the whole box.
    let aim = c + 0.5 * (hexagon.vertices()[1] - c);
    let fit = fit_opening(&scene, &facing, pixel_of(&facing, aim), facing.aspect).unwrap();
    let (lo, hi) = hexagon
        .vertices()
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), v| {
            (lo.min(*v), hi.max(*v))
        });
    let bbox = [
        Vec3::new(2.0, lo.y, lo.z),
        Vec3::new(2.0, lo.y, hi.z),
        Vec3::new(2.0, hi.y, hi.z),
        Vec3::new(2.0, hi.y, lo.z),
    ];
    assert_same_corners(&fit, &bbox);
    assert!(fit.normal.abs_diff_eq(-Vec3::X, 1e-4), "{}", fit.normal);
    assert_faces_camera(&scene, &fit, facing.eye);
}

#[test]
fn a_plain_wall_or_the_floor_has_no_opening() {
    for name in ["window", "windows2"] {
        let scene = Scene::open(name).unwrap();
        let camera = scene.camera;
        // The north wall beside the window, the west wall, the floor, the object.
        for p in [
            Vec3::new(1.5, 1.5, -2.0),
            Vec3::new(-2.0, 1.5, 0.5),
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(-0.35, 0.42, 0.75),
        ] {
            let fit = fit_opening(&scene, &camera, pixel_of(&camera, p), camera.aspect);
            assert!(fit.is_none(), "{name}: an opening at {p}: {fit:?}");
        }
    }
}
