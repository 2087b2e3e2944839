//! Built-in scenes, made in code so that the viewer and the tests need no files:
//! `lampshade` (the thesis's Figure 1), `fig8a`, `fig8b`, `fig8c` (its Figure 8), and `window`,
//! `windows2` (a room lit by the sky through window portals).

use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::sync::Arc;

use crate::asset::desc::{
    MaterialDesc, MaterialTextures, MeshDesc, NormalTexture, PortalDesc, SceneDesc,
};
use crate::asset::environment::{ENVIRONMENT_TARGET, EnvImage, EnvMap, EnvironmentDesc};
use crate::asset::texture::{Image, Sampler, TextureRef};
use crate::camera::Camera;

/// Names of the built-in scenes.
pub const NAMES: [&str; 6] = ["lampshade", "fig8a", "fig8b", "fig8c", "window", "windows2"];

/// The built-in scene `name`, if there is one.
pub fn desc(name: &str) -> Option<SceneDesc> {
    match name {
        "lampshade" => Some(lampshade()),
        "fig8a" => Some(figure8(Figure8::A)),
        "fig8b" => Some(figure8(Figure8::B)),
        "fig8c" => Some(figure8(Figure8::C)),
        "window" => Some(room_with_windows("window", false)),
        "windows2" => Some(room_with_windows("windows2", true)),
        _ => None,
    }
}

/// Accumulates meshes and portals in world space.
struct Builder {
    desc: SceneDesc,
}

impl Builder {
    fn new(name: &str) -> Self {
        Builder {
            desc: SceneDesc {
                name: name.to_owned(),
                ..SceneDesc::default()
            },
        }
    }

    fn material(&mut self, m: MaterialDesc) -> usize {
        self.desc.materials.push(m);
        self.desc.materials.len() - 1
    }

    fn flat(&mut self, node: &str, material: usize, polygons: &[Vec<Vec3>]) {
        self.desc.meshes.push(flat_mesh(node, material, polygons));
    }

    /// An axis-aligned box with outward faces.
    fn cuboid(&mut self, node: &str, material: usize, lo: Vec3, hi: Vec3) {
        let c = |x: usize, y: usize, z: usize| {
            Vec3::new(
                if x == 0 { lo.x } else { hi.x },
                if y == 0 { lo.y } else { hi.y },
                if z == 0 { lo.z } else { hi.z },
            )
        };
        let faces = vec![
            vec![c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)], // -x
            vec![c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)], // +x
            vec![c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)], // -y
            vec![c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)], // +y
            vec![c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)], // -z
            vec![c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)], // +z
        ];
        self.flat(node, material, &faces);
    }

    fn portal(&mut self, name: &str, target: &str, corners: &[Vec3]) {
        let portal = PortalDesc::from_polygon(name.to_owned(), target.to_owned(), corners);
        self.desc.portals.push(portal);
    }

    fn camera(&mut self, eye: Vec3, target: Vec3, yfov_degrees: f32) {
        self.desc.camera = Some(Camera {
            eye,
            target,
            up: Vec3::Y,
            yfov: yfov_degrees.to_radians(),
            aspect: 4.0 / 3.0,
        });
    }
}

/// A horizontal rectangle at height `y`, centred at (cx, cz), facing up or down.
fn rect_y(cx: f32, cz: f32, hx: f32, hz: f32, y: f32, up: bool) -> Vec<Vec3> {
    let v = vec![
        Vec3::new(cx - hx, y, cz - hz),
        Vec3::new(cx - hx, y, cz + hz),
        Vec3::new(cx + hx, y, cz + hz),
        Vec3::new(cx + hx, y, cz - hz),
    ];
    if up { v } else { v.into_iter().rev().collect() }
}

/// Flat-shaded convex polygons (each counter-clockwise seen from its front, fanned into
/// triangles) as one mesh node.
pub fn flat_mesh(node: &str, material: usize, polygons: &[Vec<Vec3>]) -> MeshDesc {
    let mut mesh = MeshDesc {
        node_name: node.to_owned(),
        material,
        positions: Vec::new(),
        normals: Vec::new(),
        indices: Vec::new(),
        ..MeshDesc::default()
    };
    for poly in polygons {
        let base = mesh.positions.len() as u32;
        let n = (poly[1] - poly[0]).cross(poly[2] - poly[0]).normalize();
        mesh.positions.extend(poly);
        mesh.normals.extend(std::iter::repeat_n(n, poly.len()));
        for i in 1..poly.len() as u32 - 1 {
            mesh.indices.push([base, base + i, base + i + 1]);
        }
    }
    mesh
}

/// `desc` with procedural textures on every material that reflects (the emitters keep
/// theirs): a checkerboard base colour, a roughness pattern and a bumpy normal map, on
/// texture coordinates projected from world space (so that the scene is the same but for
/// its texture lookups: the benchmark's textured variant).
pub fn with_test_textures(mut desc: SceneDesc) -> SceneDesc {
    const N: u32 = 256;
    let texels =
        |f: &dyn Fn(u32, u32) -> [u8; 4]| (0..N * N).map(|i| f(i % N, i / N)).collect::<Vec<_>>();
    let checker = texels(&|x, y| {
        let v = if (x / 32 + y / 32) % 2 == 0 { 255 } else { 190 };
        [v, v, v, 255]
    });
    // Roughness in G between 0.5 and 1, no metal in B.
    let rough = texels(&|x, y| [0, 128 + ((x ^ y) & 127) as u8, 0, 255]);
    // Bumps: the normal of a height field of sines, tilted by up to about 20°.
    let bumps = texels(&|x, y| {
        let (s, t) = (x as f32 / N as f32, y as f32 / N as f32);
        let tau = std::f32::consts::TAU;
        let (dx, dy) = (0.35 * (8.0 * tau * s).cos(), 0.35 * (8.0 * tau * t).cos());
        let n = Vec3::new(-dx, -dy, 1.0).normalize();
        let encode = |c: f32| ((c * 0.5 + 0.5) * 255.0).round() as u8;
        [encode(n.x), encode(n.y), encode(n.z), 255]
    });
    let first = desc.images.len();
    for (name, t) in [("checker", checker), ("roughness", rough), ("bumps", bumps)] {
        if let Some(image) = Image::new(name.into(), N, N, t) {
            desc.images.push(Arc::new(image));
        }
    }
    let texture = |k: usize| TextureRef {
        image: first + k,
        sampler: Sampler::default(),
        tex_coord: 0,
        transform: None,
    };
    for m in desc.materials.iter_mut().filter(|m| !m.is_emissive()) {
        m.textures = MaterialTextures {
            base_color: Some(texture(0)),
            metallic_roughness: Some(texture(1)),
            normal: Some(NormalTexture {
                texture: texture(2),
                scale: 1.0,
            }),
            ..MaterialTextures::default()
        };
    }
    for mesh in &mut desc.meshes {
        // Projected along the normal's largest axis, a texture every metre.
        mesh.texcoords[0] = mesh
            .positions
            .iter()
            .zip(&mesh.normals)
            .map(|(p, n)| {
                let a = n.abs();
                if a.y >= a.x && a.y >= a.z {
                    Vec2::new(p.x, p.z)
                } else if a.x >= a.z {
                    Vec2::new(p.z, p.y)
                } else {
                    Vec2::new(p.x, p.y)
                }
            })
            .collect();
    }
    desc.name.push_str("-textured");
    desc
}

#[derive(Clone, Copy)]
enum Figure8 {
    A,
    B,
    C,
}

/// Figure 8: a curved object on a floor, lit by a rectangular light inside an opaque box whose
/// only opening (the portal) faces the object from above.
fn figure8(which: Figure8) -> SceneDesc {
    // (opening centre x, opening half-size, light centre x, light half-size, radiance)
    let (ox, oh, lx, lh, le, name): (f32, f32, f32, f32, f32, &str) = match which {
        // Small opening, large light: the object sees only light through it (antiantumbra).
        Figure8::A => (0.0, 0.15, 0.0, 0.6, 60.0, "fig8a"),
        // Large opening, small light: the whole light is seen through it (antiumbra).
        Figure8::B => (0.0, 0.6, 0.0, 0.15, 60.0, "fig8b"),
        // Similar sizes, offset: they only partly overlap (antipenumbra).
        Figure8::C => (0.3, 0.4, -0.3, 0.4, 25.0, "fig8c"),
    };
    let mut b = Builder::new(name);
    let floor = b.material(MaterialDesc::diffuse("floor", Vec3::splat(0.6)));
    let object = b.material(MaterialDesc {
        roughness: 0.5,
        ..MaterialDesc::diffuse("object", Vec3::new(0.8, 0.55, 0.3))
    });
    let walls = b.material(MaterialDesc::diffuse("box", Vec3::splat(0.35)));
    let light = b.material(MaterialDesc::emitter("light", Vec3::splat(le), false));

    b.flat("floor", floor, &[rect_y(0.0, 0.0, 6.0, 6.0, 0.0, true)]);
    let blob = blob(Vec3::new(0.0, 0.55, 0.0), 0.5, 4);
    b.desc.meshes.push(MeshDesc {
        material: object,
        ..blob
    });

    // The box: opening plate at y0, light at y0 + depth facing down, lid just above.
    let (y0, depth) = (2.5, 0.3);
    let half = oh.max(lh) + ox.abs().max(lx.abs()) + 0.1;
    let (o0, o1) = (ox - oh, ox + oh);
    let plate = vec![
        rect_span(-half, o0, -half, half, y0),
        rect_span(o1, half, -half, half, y0),
        rect_span(o0, o1, -half, -oh, y0),
        rect_span(o0, o1, oh, half, y0),
    ];
    b.flat("box_plate", walls, &plate);
    let top = y0 + depth + 0.05;
    let sides = vec![
        rect_y(0.0, 0.0, half, half, top, true),
        wall_x(-half, y0, top, half),
        wall_x(half, y0, top, half),
        wall_z(-half, y0, top, half),
        wall_z(half, y0, top, half),
    ];
    b.flat("box_walls", walls, &sides);
    b.flat(
        "light",
        light,
        &[rect_y(lx, 0.0, lh, lh, y0 + depth, false)],
    );
    b.portal("portal", "light", &rect_y(ox, 0.0, oh, oh, y0, false));
    b.camera(Vec3::new(0.0, 1.5, 3.6), Vec3::new(0.0, 0.7, 0.0), 40.0);
    b.desc
}

/// A horizontal rectangle spanning [x0, x1] × [z0, z1] at height y, facing down.
fn rect_span(x0: f32, x1: f32, z0: f32, z1: f32, y: f32) -> Vec<Vec3> {
    vec![
        Vec3::new(x0, y, z0),
        Vec3::new(x1, y, z0),
        Vec3::new(x1, y, z1),
        Vec3::new(x0, y, z1),
    ]
}

fn wall_x(x: f32, y0: f32, y1: f32, h: f32) -> Vec<Vec3> {
    vec![
        Vec3::new(x, y0, -h),
        Vec3::new(x, y0, h),
        Vec3::new(x, y1, h),
        Vec3::new(x, y1, -h),
    ]
}

fn wall_z(z: f32, y0: f32, y1: f32, h: f32) -> Vec<Vec3> {
    vec![
        Vec3::new(-h, y0, z),
        Vec3::new(-h, y1, z),
        Vec3::new(h, y1, z),
        Vec3::new(h, y0, z),
    ]
}

/// The thesis used Suzanne; this is a procedural stand-in: a displaced icosphere with
/// `20 · 4^subdivisions` triangles and smooth normals.
fn blob(center: Vec3, radius: f32, subdivisions: u32) -> MeshDesc {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut dirs: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut faces: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |a: u32, b: u32, dirs: &mut Vec<Vec3>| {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                dirs.push((dirs[a as usize] + dirs[b as usize]).normalize());
                dirs.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(faces.len() * 4);
        for [a, b, c] in faces {
            let ab = mid(a, b, &mut dirs);
            let bc = mid(b, c, &mut dirs);
            let ca = mid(c, a, &mut dirs);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        faces = next;
    }
    // Smooth bumps and a squashed base, so that the surface curves in every direction.
    let shape = |d: Vec3| {
        let bumps = 0.12 * (3.0 * d.x + 1.0).sin() * (2.0 * d.y).cos() * (2.5 * d.z + 0.5).sin()
            + 0.08 * (4.0 * d.y).cos();
        let squash = if d.y < 0.0 { 1.0 + 0.25 * d.y } else { 1.0 };
        radius * (1.0 + bumps) * squash
    };
    let positions: Vec<Vec3> = dirs.iter().map(|&d| center + d * shape(d)).collect();
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for &[a, b, c] in &faces {
        let (pa, pb, pc) = (
            positions[a as usize],
            positions[b as usize],
            positions[c as usize],
        );
        let n = (pb - pa).cross(pc - pa);
        for i in [a, b, c] {
            normals[i as usize] += n;
        }
    }
    MeshDesc {
        node_name: "object".to_owned(),
        material: 0,
        positions,
        normals: normals.into_iter().map(|n| n.normalize_or_zero()).collect(),
        indices: faces,
        ..MeshDesc::default()
    }
}

/// Figure 1: a table lamp in a room; its two-sided rectangular light is hidden inside an
/// octagonal shade open at the top and the bottom, one portal on each opening.
fn lampshade() -> SceneDesc {
    let mut b = Builder::new("lampshade");
    let floor = b.material(MaterialDesc::diffuse("floor", Vec3::new(0.45, 0.33, 0.22)));
    let wall = b.material(MaterialDesc::diffuse("wall", Vec3::splat(0.75)));
    let wood = b.material(MaterialDesc {
        roughness: 0.4,
        ..MaterialDesc::diffuse("table", Vec3::new(0.35, 0.2, 0.1))
    });
    let metal = b.material(MaterialDesc {
        metallic: 1.0,
        roughness: 0.3,
        ..MaterialDesc::diffuse("brass", Vec3::new(0.9, 0.7, 0.35))
    });
    let fabric = b.material(MaterialDesc::diffuse("shade", Vec3::new(0.85, 0.75, 0.55)));
    let bulb = b.material(MaterialDesc::emitter(
        "bulb",
        Vec3::new(100.0, 90.0, 75.0),
        true,
    ));

    // The room, faces pointing inwards.
    let (w, h) = (3.0, 2.6);
    b.flat("floor", floor, &[rect_y(0.0, 0.0, w, w, 0.0, true)]);
    let room = vec![
        rect_y(0.0, 0.0, w, w, h, false),
        wall_x(-w, 0.0, h, w).into_iter().rev().collect(),
        wall_x(w, 0.0, h, w),
        wall_z(-w, 0.0, h, w).into_iter().rev().collect(),
        wall_z(w, 0.0, h, w),
    ];
    b.flat("walls", wall, &room);

    // The table.
    let (tx, tz, ty) = (0.0, -1.0, 0.75);
    b.cuboid(
        "table_top",
        wood,
        Vec3::new(tx - 0.7, ty - 0.05, tz - 0.4),
        Vec3::new(tx + 0.7, ty, tz + 0.4),
    );
    for (i, (sx, sz)) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
        .into_iter()
        .enumerate()
    {
        let c = Vec3::new(tx + sx * 0.62, 0.0, tz + sz * 0.32);
        b.cuboid(
            &format!("table_leg_{i}"),
            wood,
            c - Vec3::new(0.03, 0.0, 0.03),
            c + Vec3::new(0.03, ty - 0.05, 0.03),
        );
    }

    // The lamp: base, stem, shade, bulb.
    let base = Vec3::new(tx, ty, tz);
    b.cuboid(
        "lamp_base",
        metal,
        base - Vec3::new(0.1, 0.0, 0.1),
        base + Vec3::new(0.1, 0.03, 0.1),
    );
    let (y_bottom, y_top, y_light) = (ty + 0.3, ty + 0.62, ty + 0.45);
    b.cuboid(
        "lamp_stem",
        metal,
        base + Vec3::new(-0.012, 0.03, -0.012),
        base + Vec3::new(0.012, y_light - ty - 0.02, 0.012),
    );
    let (r_bottom, r_top, sides) = (0.24, 0.16, 8);
    let ring = |r: f32, y: f32| -> Vec<Vec3> {
        (0..sides)
            .map(|i| {
                let a = std::f32::consts::TAU * (i as f32 + 0.5) / sides as f32;
                Vec3::new(tx + r * a.cos(), y, tz + r * a.sin())
            })
            .collect()
    };
    let (bottom, top) = (ring(r_bottom, y_bottom), ring(r_top, y_top));
    let shade: Vec<Vec<Vec3>> = (0..sides)
        .map(|i| {
            let j = (i + 1) % sides;
            vec![bottom[i], top[i], top[j], bottom[j]]
        })
        .collect();
    b.flat("lamp_shade", fabric, &shade);
    b.flat("bulb", bulb, &[rect_y(tx, tz, 0.07, 0.07, y_light, true)]);
    b.portal("portal_top", "bulb", &top);
    b.portal("portal_bottom", "bulb", &bottom);
    b.camera(Vec3::new(1.7, 1.55, 1.4), Vec3::new(0.0, 1.05, -1.0), 50.0);
    b.desc
}

/// The direction towards the built-in sky's sun: 29° above the horizon, towards −Z and a
/// little +X, so that it shines through the north window onto the floor.
pub fn sky_sun_direction() -> Vec3 {
    Vec3::new(0.25, 0.55, -1.0).normalize()
}

/// The sun's angular radius (radians) and radiance in the built-in sky.
pub const SKY_SUN_RADIUS: f32 = 0.045;
pub const SKY_SUN_RADIANCE: Vec3 = Vec3::new(1500.0, 1400.0, 1200.0);

/// The built-in sky: a blue gradient over a dim ground, with a sun-like hot spot, as a
/// 512 × 256 equirectangular image (Blender's mapping, rotation 0).
pub fn sky_image() -> EnvImage {
    let (width, height) = (512u32, 256u32);
    let sun = sky_sun_direction();
    let sun_cos = SKY_SUN_RADIUS.cos();
    let mut pixels = Vec::with_capacity((width * height) as usize);
    for j in 0..height {
        for i in 0..width {
            let theta = std::f32::consts::PI * (j as f32 + 0.5) / height as f32;
            let phi = std::f32::consts::TAU * ((i as f32 + 0.5) / width as f32 - 0.5);
            let d = Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            );
            let radiance = if d.dot(sun) >= sun_cos {
                SKY_SUN_RADIANCE
            } else if d.y >= 0.0 {
                let horizon = Vec3::new(1.1, 1.05, 0.95);
                let zenith = Vec3::new(0.3, 0.5, 1.0);
                horizon.lerp(zenith, d.y.sqrt())
                    + Vec3::new(0.6, 0.5, 0.35) * d.dot(sun).max(0.0).powi(8)
            } else {
                Vec3::new(0.22, 0.19, 0.15)
            };
            pixels.push(radiance);
        }
    }
    EnvImage {
        width,
        height,
        pixels,
    }
}

/// Corners of a wall polygon given in the wall's own `(u, v)` coordinates, wound so that its
/// front faces `inward`.
fn facing(corners: Vec<Vec3>, inward: Vec3) -> Vec<Vec3> {
    let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
    if n.dot(inward) >= 0.0 {
        corners
    } else {
        corners.into_iter().rev().collect()
    }
}

/// The rectangle `[u0, u1] × [v0, v1]` less the convex `hole` (counter-clockwise, strictly
/// inside), as convex pieces in `(u, v)`: full-width bands above and below the hole, and
/// between consecutive vertex heights one trapezoid on either side of it.
fn rectangle_less_hole(u: [f32; 2], v: [f32; 2], hole: &[Vec2]) -> Vec<Vec<Vec2>> {
    let (lo, hi) = hole
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    // The hole's extent along u at height y (a convex polygon's cross-section).
    let span = |y: f32| {
        let mut left = f32::INFINITY;
        let mut right = f32::NEG_INFINITY;
        for k in 0..hole.len() {
            let (a, b) = (hole[k], hole[(k + 1) % hole.len()]);
            if (a.y - y) * (b.y - y) <= 0.0 && a.y != b.y {
                let x = a.x + (b.x - a.x) * (y - a.y) / (b.y - a.y);
                left = left.min(x);
                right = right.max(x);
            } else if a.y == y {
                left = left.min(a.x);
                right = right.max(a.x);
            }
        }
        (left, right)
    };
    let mut levels: Vec<f32> = hole.iter().map(|p| p.y).collect();
    levels.sort_by(f32::total_cmp);
    levels.dedup();
    let mut pieces = vec![
        vec![
            Vec2::new(u[0], v[0]),
            Vec2::new(u[1], v[0]),
            Vec2::new(u[1], lo),
            Vec2::new(u[0], lo),
        ],
        vec![
            Vec2::new(u[0], hi),
            Vec2::new(u[1], hi),
            Vec2::new(u[1], v[1]),
            Vec2::new(u[0], v[1]),
        ],
    ];
    for w in levels.windows(2) {
        let (ya, yb) = (w[0], w[1]);
        let ((la, ra), (lb, rb)) = (span(ya), span(yb));
        pieces.push(vec![
            Vec2::new(u[0], ya),
            Vec2::new(la, ya),
            Vec2::new(lb, yb),
            Vec2::new(u[0], yb),
        ]);
        pieces.push(vec![
            Vec2::new(ra, ya),
            Vec2::new(u[1], ya),
            Vec2::new(u[1], yb),
            Vec2::new(rb, yb),
        ]);
    }
    pieces
}

/// A closed room, 4 × 2.6 × 4 m, lit by the built-in sky through a window in its north wall
/// (−Z); with `two`, a smaller north window and a hexagonal one in the east wall (+X). Each
/// window's portal fills its opening, facing into the room.
fn room_with_windows(name: &str, two: bool) -> SceneDesc {
    let mut b = Builder::new(name);
    let floor = b.material(MaterialDesc::diffuse("floor", Vec3::new(0.55, 0.45, 0.35)));
    let wall = b.material(MaterialDesc::diffuse("wall", Vec3::splat(0.75)));
    let object = b.material(MaterialDesc {
        roughness: 0.5,
        ..MaterialDesc::diffuse("object", Vec3::new(0.8, 0.55, 0.3))
    });
    let (w, h) = (2.0, 2.6);
    // The north wall at z = −w: u along +x, v up; the east wall at x = +w: u along +z.
    let north = |p: Vec2| Vec3::new(p.x, p.y, -w);
    let east = |p: Vec2| Vec3::new(w, p.y, p.x);
    let north_window: Vec<Vec2> = if two {
        vec![
            Vec2::new(-0.9, 0.9),
            Vec2::new(-0.1, 0.9),
            Vec2::new(-0.1, 2.0),
            Vec2::new(-0.9, 2.0),
        ]
    } else {
        vec![
            Vec2::new(-0.8, 0.8),
            Vec2::new(0.8, 0.8),
            Vec2::new(0.8, 2.1),
            Vec2::new(-0.8, 2.1),
        ]
    };
    let hexagon: Vec<Vec2> = (0..6)
        .map(|k| {
            let a = std::f32::consts::TAU * k as f32 / 6.0;
            Vec2::new(0.2, 1.45) + 0.55 * Vec2::new(a.cos(), a.sin())
        })
        .collect();

    let mut walls: Vec<Vec<Vec3>> = Vec::new();
    let wall_pieces = |hole: Option<&[Vec2]>, map: &dyn Fn(Vec2) -> Vec3, inward: Vec3| {
        let pieces = match hole {
            Some(hole) => rectangle_less_hole([-w, w], [0.0, h], hole),
            None => vec![vec![
                Vec2::new(-w, 0.0),
                Vec2::new(w, 0.0),
                Vec2::new(w, h),
                Vec2::new(-w, h),
            ]],
        };
        pieces
            .into_iter()
            .map(|p| facing(p.into_iter().map(map).collect(), inward))
            .collect::<Vec<_>>()
    };
    walls.extend(wall_pieces(Some(&north_window), &north, Vec3::Z));
    walls.extend(wall_pieces(two.then_some(&hexagon[..]), &east, -Vec3::X));
    walls.extend(wall_pieces(None, &|p| Vec3::new(p.x, p.y, w), -Vec3::Z));
    walls.extend(wall_pieces(None, &|p| Vec3::new(-w, p.y, p.x), Vec3::X));
    walls.push(rect_y(0.0, 0.0, w, w, h, false));
    b.flat("floor", floor, &[rect_y(0.0, 0.0, w, w, 0.0, true)]);
    b.flat("walls", wall, &walls);
    let blob = blob(Vec3::new(-0.35, 0.42, 0.35), 0.4, 3);
    b.desc.meshes.push(MeshDesc {
        material: object,
        ..blob
    });

    let window_corners = |hole: &[Vec2], map: &dyn Fn(Vec2) -> Vec3, inward: Vec3| {
        facing(hole.iter().map(|&p| map(p)).collect(), inward)
    };
    b.portal(
        "window_north",
        ENVIRONMENT_TARGET,
        &window_corners(&north_window, &north, Vec3::Z),
    );
    if two {
        b.portal(
            "window_east",
            ENVIRONMENT_TARGET,
            &window_corners(&hexagon, &east, -Vec3::X),
        );
    }
    b.desc.environment = Some(EnvironmentDesc {
        map: EnvMap::Image {
            file: None,
            image: Arc::new(sky_image()),
        },
        strength: 1.0,
        rotation_degrees: 0.0,
    });
    b.camera(Vec3::new(1.5, 1.5, 1.85), Vec3::new(-0.4, 0.7, -0.6), 62.0);
    b.desc
}
