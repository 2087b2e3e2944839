//! Built-in scenes, made in code so that the viewer and the tests need no files:
//! `lampshade` (the thesis's Figure 1), `fig8a`, `fig8b`, `fig8c` (its Figure 8), `window`,
//! `windows2` (a room lit by the sky through window portals), `desklamp` (an artist's scene
//! as Blender exports it: textures, a normal map, a point lamp and a bulb mesh behind portals),
//! `livingroom` (many lights in one room: eight lamps, six ceiling cans and a window, each
//! behind its portals), and glass: `panes` (`windows2` with a glass pane in each window) and
//! `pendant` (a bulb in a clear glass globe, in a room lit through a glazed window).

mod livingroom;

use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::sync::Arc;

use crate::asset::desc::{
    LampDesc, LampKind, MaterialDesc, MaterialTextures, MeshDesc, NormalTexture, PortalDesc,
    SceneDesc,
};
use crate::asset::environment::{
    ENVIRONMENT_TARGET, EnvImage, EnvMap, EnvironmentDesc, Interpolation,
};
use crate::asset::texture::{Image, Sampler, TextureRef};
use crate::camera::Camera;

/// Names of the built-in scenes.
pub const NAMES: [&str; 10] = [
    "lampshade",
    "fig8a",
    "fig8b",
    "fig8c",
    "window",
    "windows2",
    "desklamp",
    "livingroom",
    "panes",
    "pendant",
];

/// The built-in scene `name`, if there is one.
pub fn desc(name: &str) -> Option<SceneDesc> {
    match name {
        "lampshade" => Some(lampshade()),
        "fig8a" => Some(figure8(Figure8::A)),
        "fig8b" => Some(figure8(Figure8::B)),
        "fig8c" => Some(figure8(Figure8::C)),
        "window" => Some(room_with_windows("window", false)),
        "windows2" => Some(room_with_windows("windows2", true)),
        "panes" => Some(panes()),
        "pendant" => Some(pendant()),
        "desklamp" => Some(desklamp()),
        "livingroom" => Some(livingroom::livingroom()),
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
        self.flat(node, material, &cuboid_faces(lo, hi));
    }

    /// Axis-aligned boxes `(lo, hi)` with outward faces, as one node.
    fn cuboids(&mut self, node: &str, material: usize, boxes: &[(Vec3, Vec3)]) {
        let faces: Vec<Vec<Vec3>> = boxes
            .iter()
            .flat_map(|&(lo, hi)| cuboid_faces(lo, hi))
            .collect();
        self.flat(node, material, &faces);
    }

    /// A lamp shade `lamp_shade`: a frustum of `sides` quads about the vertical axis through
    /// `(cx, cz)`, open at both ends, from the ring (radius, height) `bottom` to `top`, its
    /// vertices at angles `(i + phase) / sides` turns. Returns the two rings (the openings).
    fn shade(
        &mut self,
        material: usize,
        (cx, cz): (f32, f32),
        (r_bottom, y_bottom): (f32, f32),
        (r_top, y_top): (f32, f32),
        sides: usize,
        phase: f32,
    ) -> (Vec<Vec3>, Vec<Vec3>) {
        let ring = |r: f32, y: f32| -> Vec<Vec3> {
            (0..sides)
                .map(|i| {
                    let a = std::f32::consts::TAU * (i as f32 + phase) / sides as f32;
                    Vec3::new(cx + r * a.cos(), y, cz + r * a.sin())
                })
                .collect()
        };
        let (bottom, top) = (ring(r_bottom, y_bottom), ring(r_top, y_top));
        let quads: Vec<Vec<Vec3>> = (0..sides)
            .map(|i| {
                let j = (i + 1) % sides;
                vec![bottom[i], top[i], top[j], bottom[j]]
            })
            .collect();
        self.flat("lamp_shade", material, &quads);
        (bottom, top)
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

/// The six faces of the axis-aligned box from `lo` to `hi`, each facing out.
fn cuboid_faces(lo: Vec3, hi: Vec3) -> Vec<Vec<Vec3>> {
    let c = |x: usize, y: usize, z: usize| {
        Vec3::new(
            if x == 0 { lo.x } else { hi.x },
            if y == 0 { lo.y } else { hi.y },
            if z == 0 { lo.z } else { hi.z },
        )
    };
    vec![
        vec![c(0, 0, 0), c(0, 0, 1), c(0, 1, 1), c(0, 1, 0)], // -x
        vec![c(1, 0, 0), c(1, 1, 0), c(1, 1, 1), c(1, 0, 1)], // +x
        vec![c(0, 0, 0), c(1, 0, 0), c(1, 0, 1), c(0, 0, 1)], // -y
        vec![c(0, 1, 0), c(0, 1, 1), c(1, 1, 1), c(1, 1, 0)], // +y
        vec![c(0, 0, 0), c(0, 1, 0), c(1, 1, 0), c(1, 0, 0)], // -z
        vec![c(0, 0, 1), c(1, 0, 1), c(1, 1, 1), c(0, 1, 1)], // +z
    ]
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
        // A texture every metre.
        mesh.texcoords[0] = projected_uvs(mesh, 1.0);
    }
    desc.name.push_str("-textured");
    desc
}

/// Texture coordinates projected from world space along each vertex normal's largest axis,
/// `per_metre` texture repeats a metre (so flat-shaded boxes get a seamless texture per face).
fn projected_uvs(mesh: &MeshDesc, per_metre: f32) -> Vec<Vec2> {
    mesh.positions
        .iter()
        .zip(&mesh.normals)
        .map(|(p, n)| {
            let a = n.abs();
            let uv = if a.y >= a.x && a.y >= a.z {
                Vec2::new(p.x, p.z)
            } else if a.x >= a.z {
                Vec2::new(p.z, p.y)
            } else {
                Vec2::new(p.x, p.y)
            };
            uv * per_metre
        })
        .collect()
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
    let (bottom, top) = b.shade(fabric, (tx, tz), (0.24, y_bottom), (0.16, y_top), 8, 0.5);
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
    // The measurements in docs/performance.md were made on this sky's pixels as cells.
    b.desc.environment = Some(generated_sky(Interpolation::Closest));
    b.camera(Vec3::new(1.5, 1.5, 1.85), Vec3::new(-0.4, 0.7, -0.6), 62.0);
    b.desc
}

/// How far outside the wall plane a window's pane stands: its inner face 1 cm out, so the
/// window portal (in the wall's plane) lies 1 cm inside the glass, as an artist places it.
const PANE_GAP: f32 = 0.01;
/// A pane's thickness: 6 mm of glass, modelled as a closed slab (two thin-walled surfaces).
const PANE_THICKNESS: f32 = 0.006;
/// How far a pane reaches past its opening's edges, behind the wall, so no ray slips around it.
const PANE_OVERLAP: f32 = 0.03;

/// The closed slab over the convex polygon `corners` (in a plane) between offsets `near` and
/// `far` along `normal`, grown by `grow` about its centroid: a pane of glass. Faces point out.
pub fn slab(corners: &[Vec3], normal: Vec3, (near, far): (f32, f32), grow: f32) -> Vec<Vec<Vec3>> {
    let centre = corners.iter().copied().sum::<Vec3>() / corners.len() as f32;
    let grown: Vec<Vec3> = corners
        .iter()
        .map(|&p| p + (p - centre).normalize_or_zero() * grow)
        .collect();
    let near_face: Vec<Vec3> = grown.iter().map(|&p| p + near * normal).collect();
    let far_face: Vec<Vec3> = grown.iter().map(|&p| p + far * normal).collect();
    let mid = centre + 0.5 * (near + far) * normal;
    let out = |face: Vec<Vec3>| {
        let c = face.iter().copied().sum::<Vec3>() / face.len() as f32;
        facing(face, c - mid)
    };
    let n = grown.len();
    let mut faces = vec![out(near_face.clone()), out(far_face.clone())];
    for i in 0..n {
        let j = (i + 1) % n;
        faces.push(out(vec![
            near_face[i],
            near_face[j],
            far_face[j],
            far_face[i],
        ]));
    }
    faces
}

/// `windows2` with glass in both windows, as an artist models it: each pane a 6 mm slab of
/// clear glass (glTF transmission, thin-walled: no volume) 1 cm outside its window portal.
/// The same room, sky and camera, so its renders compare with `windows2`'s.
fn panes() -> SceneDesc {
    let mut desc = room_with_windows("panes", true);
    add_panes(&mut desc);
    desc
}

/// A pane over every window portal of `desc`, outside the room (behind the portal's front);
/// returns the glass's material.
fn add_panes(desc: &mut SceneDesc) -> usize {
    let glass = desc.materials.len();
    desc.materials.push(MaterialDesc::clear_glass("glass"));
    let windows: Vec<(String, Vec<Vec3>)> = desc
        .portals
        .iter()
        .filter(|p| p.is_window())
        .filter_map(|p| {
            let fan = p.world_triangles();
            let mut corners: Vec<Vec3> = vec![fan.first()?[0]];
            corners.extend(fan.iter().flat_map(|t| [t[1], t[2]]));
            corners.dedup();
            Some((p.name.clone(), corners))
        })
        .collect();
    for (name, corners) in windows {
        // The portal faces into the room: the pane stands on its back.
        let inward = (corners[1] - corners[0])
            .cross(corners[2] - corners[0])
            .normalize();
        let faces = slab(
            &corners,
            -inward,
            (PANE_GAP, PANE_GAP + PANE_THICKNESS),
            PANE_OVERLAP,
        );
        desc.meshes
            .push(flat_mesh(&format!("{name}_pane"), glass, &faces));
    }
    glass
}

/// A pendant lamp whose bulb hangs inside a clear glass globe (two concentric spheres of thin
/// glass, as Blender exports them), in the `window` room, whose window has a pane. The bulb
/// has no portal: its light is sampled through the globe.
fn pendant() -> SceneDesc {
    let mut desc = room_with_windows("pendant", false);
    let glass = add_panes(&mut desc);
    let mut b = Builder { desc };
    let cord = b.material(MaterialDesc::diffuse("cord", Vec3::splat(0.05)));
    let bulb = b.material(MaterialDesc::emitter(
        "bulb",
        Vec3::new(2000.0, 1800.0, 1500.0),
        true,
    ));
    let centre = Vec3::new(0.3, 1.75, -0.2);
    let (r_outer, r_inner, r_bulb) = (0.12, 0.114, 0.03);
    b.cuboid(
        "cord",
        cord,
        centre + Vec3::new(-0.004, r_outer, -0.004),
        Vec3::new(centre.x + 0.004, 2.6, centre.z + 0.004),
    );
    b.desc
        .meshes
        .push(uv_sphere("globe_outer", glass, centre, r_outer, 32, 16));
    // The inner surface faces into the globe: its triangles wound the other way.
    let mut inner = uv_sphere("globe_inner", glass, centre, r_inner, 32, 16);
    for t in &mut inner.indices {
        t.swap(1, 2);
    }
    for n in &mut inner.normals {
        *n = -*n;
    }
    b.desc.meshes.push(inner);
    b.desc
        .meshes
        .push(uv_sphere("bulb", bulb, centre, r_bulb, 12, 6));
    b.desc
}

/// The generated sky ([`sky_image`]) as the scene's environment.
fn generated_sky(interpolation: Interpolation) -> EnvironmentDesc {
    EnvironmentDesc {
        map: EnvMap::Image {
            file: None,
            image: Arc::new(sky_image()),
        },
        strength: 1.0,
        rotation_degrees: 0.0,
        interpolation,
    }
}

/// Adds an `n`×`n` image of texels `f(x, y)` to the scene; a reference to it with the default
/// (repeating, bilinear) sampler on `TEXCOORD_0`.
fn procedural_texture(
    desc: &mut SceneDesc,
    name: &str,
    n: u32,
    f: impl Fn(u32, u32) -> [u8; 4],
) -> Option<TextureRef> {
    let texels = (0..n * n).map(|i| f(i % n, i / n)).collect();
    let image = Image::new(name.to_owned(), n, n, texels)?;
    desc.images.push(Arc::new(image));
    Some(TextureRef {
        image: desc.images.len() - 1,
        sampler: Sampler::default(),
        tex_coord: 0,
        transform: None,
    })
}

/// A small integer hash to [0, 1), for procedural texture variation.
fn hash01(k: u32) -> f32 {
    let mut h = k.wrapping_mul(0x9E37_79B9) ^ 0x85EB_CA6B;
    h ^= h >> 15;
    h = h.wrapping_mul(0x2C1B_3C6D);
    h ^= h >> 12;
    (h & 0xFFFF) as f32 / 65536.0
}

/// An sRGB byte of a linear value in [0, 1].
fn srgb_byte(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// A UV sphere: `segments` around, `rings` from pole to pole (one vertex at each pole, so
/// `segments · (rings − 1) + 2` vertices), smooth normals pointing out.
fn uv_sphere(
    node: &str,
    material: usize,
    center: Vec3,
    radius: f32,
    segments: u32,
    rings: u32,
) -> MeshDesc {
    let mut mesh = MeshDesc {
        node_name: node.to_owned(),
        material,
        ..MeshDesc::default()
    };
    let mut vertex = |d: Vec3| {
        mesh.positions.push(center + radius * d);
        mesh.normals.push(d);
    };
    vertex(Vec3::Y);
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = std::f32::consts::TAU * s as f32 / segments as f32;
            vertex(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ));
        }
    }
    vertex(Vec3::NEG_Y);
    let south = segments * (rings - 1) + 1;
    // Ring r (1 ..= rings − 1), segment s.
    let at = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    // Counter-clockwise seen from outside (y up, φ turning from +x towards +z).
    for s in 0..segments {
        mesh.indices.push([0, at(1, s + 1), at(1, s)]);
        mesh.indices
            .push([south, at(rings - 1, s), at(rings - 1, s + 1)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (at(r, s), at(r, s + 1), at(r + 1, s + 1), at(r + 1, s));
            mesh.indices.push([a, b, c]);
            mesh.indices.push([a, c, d]);
        }
    }
    mesh
}

/// An artist's scene, made as Blender's glTF exporter writes one: a desk in a room corner, lit by
/// a desk lamp whose bulb (a UV-sphere emissive mesh) hides in a conical shade open at both ends,
/// one portal on each opening, and by a ceiling point lamp (`KHR_lights_punctual`). Textures: a
/// wood-plank floor, a wood desk top, a plaster wall with a normal map (tangents generated on
/// load), a checkered block with a roughness/metal texture. Matte materials carry
/// `KHR_materials_specular` with a black specular colour, as Blender writes a Principled BSDF of
/// Specular 0: pure Lambert.
fn desklamp() -> SceneDesc {
    let mut b = Builder::new("desklamp");
    let d = &mut b.desc;
    // Floor planks 0.2 m wide (rows of 32 texels): a tint per plank, grain along the plank.
    let planks = procedural_texture(d, "floor_planks", 256, |x, y| {
        let plank = y / 32;
        let seam = y % 32 == 0 || (x + 97 * plank) % 256 < 2;
        let tint = 0.8 + 0.4 * hash01(plank * 7 + 3);
        let t = x as f32 / 256.0 + hash01(plank) * 5.0;
        let grain = 0.85 + 0.15 * (40.0 * t + 3.0 * (y as f32 * 0.3).sin()).sin();
        let k = if seam { 0.35 } else { tint * grain };
        [
            srgb_byte(0.42 * k),
            srgb_byte(0.25 * k),
            srgb_byte(0.13 * k),
            255,
        ]
    });
    // Desk top: a darker, finer grain.
    let desk_wood = procedural_texture(d, "desk_wood", 256, |x, y| {
        let t = y as f32 / 256.0 * std::f32::consts::TAU;
        let ring = (30.0 * t + 2.5 * (x as f32 / 256.0 * std::f32::consts::TAU * 2.0).sin()).sin();
        let k = 0.8 + 0.2 * ring;
        [
            srgb_byte(0.2 * k),
            srgb_byte(0.1 * k),
            srgb_byte(0.05 * k),
            255,
        ]
    });
    // Plaster: the normal of a rough height field (sums of sines), tilted up to about 25°.
    let plaster = procedural_texture(d, "wall_plaster_normal", 256, |x, y| {
        let (s, t) = (
            x as f32 / 256.0 * std::f32::consts::TAU,
            y as f32 / 256.0 * std::f32::consts::TAU,
        );
        let dx = 0.25 * (5.0 * s + 2.0 * (3.0 * t).sin()).cos() + 0.15 * (13.0 * s + 7.0 * t).cos();
        let dy = 0.25 * (4.0 * t + 2.0 * (2.0 * s).sin()).cos() + 0.15 * (11.0 * t - 6.0 * s).cos();
        let n = Vec3::new(-dx, -dy, 1.0).normalize();
        let encode = |c: f32| ((c * 0.5 + 0.5) * 255.0).round() as u8;
        [encode(n.x), encode(n.y), encode(n.z), 255]
    });
    // The block: an 8 × 8 checkerboard of red and cream; metallic-roughness: glossy red squares.
    let checker = procedural_texture(d, "block_checker", 128, |x, y| {
        if (x / 16 + y / 16) % 2 == 0 {
            [200, 40, 30, 255]
        } else {
            [235, 225, 200, 255]
        }
    });
    let block_mr = procedural_texture(d, "block_metal_roughness", 128, |x, y| {
        let rough = if (x / 16 + y / 16) % 2 == 0 { 90 } else { 230 };
        [0, rough, 0, 255]
    });
    // Blender's Principled BSDF with Specular 0: the exporter writes a black specular colour.
    let matte = |name: &str, color: Vec3| MaterialDesc {
        specular_color: Vec3::ZERO,
        ..MaterialDesc::diffuse(name, color)
    };
    let floor = b.material(MaterialDesc {
        roughness: 0.6,
        textures: MaterialTextures {
            base_color: planks,
            ..MaterialTextures::default()
        },
        ..MaterialDesc::diffuse("floor_wood", Vec3::ONE)
    });
    let wall = b.material(MaterialDesc {
        textures: MaterialTextures {
            normal: plaster.map(|texture| NormalTexture {
                texture,
                scale: 0.6,
            }),
            ..MaterialTextures::default()
        },
        ..matte("wall_plaster", Vec3::new(0.75, 0.72, 0.66))
    });
    let side_wall = b.material(matte("wall_paint", Vec3::new(0.45, 0.55, 0.6)));
    let desk = b.material(MaterialDesc {
        roughness: 0.35,
        textures: MaterialTextures {
            base_color: desk_wood,
            ..MaterialTextures::default()
        },
        ..MaterialDesc::diffuse("desk_wood", Vec3::ONE)
    });
    let block = b.material(MaterialDesc {
        textures: MaterialTextures {
            base_color: checker,
            metallic_roughness: block_mr,
            ..MaterialTextures::default()
        },
        ..MaterialDesc::diffuse("block_checker", Vec3::ONE)
    });
    let metal = b.material(MaterialDesc {
        metallic: 1.0,
        roughness: 0.25,
        ..MaterialDesc::diffuse("lamp_metal", Vec3::new(0.15, 0.35, 0.3))
    });
    let fabric = b.material(matte("shade_fabric", Vec3::new(0.7, 0.62, 0.5)));
    let bulb = b.material(MaterialDesc::emitter(
        "bulb_glow",
        Vec3::new(250.0, 212.0, 150.0),
        false,
    ));

    // The room corner: a floor, a back wall (z = −1.6) and a left wall (x = −2), open elsewhere.
    let (w, h, back, left) = (2.5, 3.0, -1.6, -2.0);
    b.flat("floor", floor, &[rect_y(0.0, 0.0, w, w, 0.0, true)]);
    b.flat(
        "back_wall",
        wall,
        &[vec![
            Vec3::new(-w, 0.0, back),
            Vec3::new(w, 0.0, back),
            Vec3::new(w, h, back),
            Vec3::new(-w, h, back),
        ]],
    );
    b.flat(
        "left_wall",
        side_wall,
        &[vec![
            Vec3::new(left, 0.0, -w),
            Vec3::new(left, h, -w),
            Vec3::new(left, h, w),
            Vec3::new(left, 0.0, w),
        ]],
    );

    // The desk against the back wall.
    let (x0, x1, z0, z1, ty) = (-1.5, 0.5, back + 0.05, back + 0.85, 0.75);
    b.cuboid(
        "desk_top",
        desk,
        Vec3::new(x0, ty - 0.04, z0),
        Vec3::new(x1, ty, z1),
    );
    for (i, (x, z)) in [(x0, z0), (x1, z0), (x0, z1), (x1, z1)]
        .into_iter()
        .enumerate()
    {
        let c = Vec3::new(
            x + if x == x0 { 0.05 } else { -0.05 },
            0.0,
            z + if z == z0 { 0.05 } else { -0.05 },
        );
        b.cuboid(
            &format!("desk_leg_{i}"),
            desk,
            c - Vec3::new(0.03, 0.0, 0.03),
            c + Vec3::new(0.03, ty - 0.04, 0.03),
        );
    }
    // A checkered block on the desk.
    b.cuboid(
        "block",
        block,
        Vec3::new(-0.15, ty, back + 0.45),
        Vec3::new(0.15, ty + 0.2, back + 0.65),
    );

    // The desk lamp: base, stem, a conical shade open at the bottom and the top, a bulb.
    let (lx, lz) = (-0.8, back + 0.4);
    b.cuboid(
        "lamp_base",
        metal,
        Vec3::new(lx - 0.09, ty, lz - 0.09),
        Vec3::new(lx + 0.09, ty + 0.025, lz + 0.09),
    );
    let (y_bottom, y_top, y_bulb) = (ty + 0.33, ty + 0.55, ty + 0.43);
    b.cuboid(
        "lamp_stem",
        metal,
        Vec3::new(lx - 0.01, ty + 0.025, lz - 0.01),
        Vec3::new(lx + 0.01, y_bulb - 0.05, lz + 0.01),
    );
    let (bottom, top) = b.shade(fabric, (lx, lz), (0.2, y_bottom), (0.09, y_top), 12, 0.0);
    b.desc.meshes.push(uv_sphere(
        "bulb",
        bulb,
        Vec3::new(lx, y_bulb, lz),
        0.05,
        // 23 vertices: few enough (at most 24) for the portals to bound it by its exact
        // convex hull rather than a looser prism.
        7,
        4,
    ));
    b.portal("portal_bottom", "bulb", &bottom);
    b.portal("portal_top", "bulb", &top);

    // A ceiling lamp: Blender's 100 W point lamp, written as 100 · 683 / (4π) cd.
    b.desc.lamps.push(LampDesc {
        name: "ceiling_lamp".to_owned(),
        kind: LampKind::Point,
        color: Vec3::new(1.0, 0.95, 0.9),
        intensity: 100.0 * 683.0 / (4.0 * std::f32::consts::PI),
        range: None,
        position: Vec3::new(0.6, 2.4, 0.4),
        direction: Vec3::NEG_Z,
    });

    // Texture coordinates: planks every 1.6 m, the desk grain every 1 m, plaster every 0.6 m,
    // the checkerboard across each face of the block.
    for mesh in &mut b.desc.meshes {
        let per_metre = match mesh.node_name.as_str() {
            "floor" => 1.0 / 1.6,
            "back_wall" => 1.0 / 0.6,
            "block" => 1.0 / 0.3,
            name if name.starts_with("desk") => 1.0,
            _ => continue,
        };
        mesh.texcoords[0] = projected_uvs(mesh, per_metre);
    }
    b.camera(
        Vec3::new(0.7, 1.35, 0.55),
        Vec3::new(-0.5, 0.95, -1.1),
        50.0,
    );
    b.desc
}
