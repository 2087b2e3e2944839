//! `livingroom`: many lights in one room. A closed living room 10 × 8 × 3 m (x from −5 to 5,
//! z from −4 to 4, floor at y = 0) lit by eight lamps, six ceiling cans and the built-in sky
//! through one window in the north wall (−Z, where the sun shines in). Each lamp hides two
//! one-sided square emitters back to back inside its shade, the lower facing down and the upper
//! facing up, each behind the portal of the opening it faces; each can hides a downward emitter
//! behind the portal over its open bottom. 22 area lights, 22 portals onto them and one window
//! portal; the lights' powers span 20×.

use glam::{Vec2, Vec3};

use super::{Builder, cuboid_faces, facing, generated_sky, hash01, rect_y, rectangle_less_hole};
use crate::asset::desc::{MaterialDesc, SceneDesc};
use crate::asset::environment::{ENVIRONMENT_TARGET, Interpolation};

/// The room: x in [−W, W], z in [−D, D], y in [0, H].
const W: f32 = 5.0;
const D: f32 = 4.0;
const H: f32 = 3.0;

/// The window in the north wall (z = −D), 1.6 × 1.2 m: corners (x, y), counter-clockwise.
const WINDOW: [Vec2; 4] = [
    Vec2::new(-0.6, 0.9),
    Vec2::new(1.0, 0.9),
    Vec2::new(1.0, 2.1),
    Vec2::new(-0.6, 2.1),
];

/// The lamps' light colour (its brightest channel 1): warm white.
const WARM: Vec3 = Vec3::new(1.0, 0.8, 0.58);
/// The cans' light colour: a whiter white.
const NEUTRAL: Vec3 = Vec3::new(1.0, 0.93, 0.84);

/// A lamp: a base, a stem, an octagonal shade open at both ends, and inside the shade two
/// square emitters back to back, the lower facing down and the upper facing up.
struct Lamp {
    /// The centre of its base (x, z) and the height of what it stands on (0: a floor lamp).
    at: (f32, f32, f32),
    /// The shade's bottom and top radii, its bottom's height above the base, its height.
    shade: (f32, f32, f32, f32),
    /// The radiance of the emitter facing down and of the one facing up (the light colour's
    /// brightest channel).
    radiance: (f32, f32),
}

/// Half the side of a lamp's emitters (10 × 10 cm each).
const LAMP_EMITTER_HALF: f32 = 0.05;

/// The lamps, `lamp1` to `lamp8` in node names; their emitters' powers (π · L · A) span 4×,
/// 6.3 to 25 W.
const LAMPS: [Lamp; 8] = [
    // 1, 2: on the side tables at either end of the sofa.
    Lamp {
        at: (-3.8, 1.35, 0.55),
        shade: (0.2, 0.14, 0.2, 0.28),
        radiance: (440.0, 300.0),
    },
    Lamp {
        at: (-0.8, 1.35, 0.55),
        shade: (0.2, 0.14, 0.2, 0.28),
        radiance: (440.0, 300.0),
    },
    // 3: a small accent lamp on top of the bookshelf, the dimmest light.
    Lamp {
        at: (-4.8, -2.1, 2.0),
        shade: (0.12, 0.08, 0.1, 0.18),
        radiance: (200.0, 200.0),
    },
    // 4: a floor lamp in the north-west corner.
    Lamp {
        at: (-4.4, -3.4, 0.0),
        shade: (0.24, 0.16, 1.45, 0.32),
        radiance: (600.0, 600.0),
    },
    // 5: on the console table against the north wall.
    Lamp {
        at: (-1.45, -3.76, 0.8),
        shade: (0.18, 0.12, 0.22, 0.24),
        radiance: (360.0, 240.0),
    },
    // 6: on the sideboard against the east wall.
    Lamp {
        at: (4.75, 0.5, 0.85),
        shade: (0.18, 0.12, 0.22, 0.24),
        radiance: (360.0, 240.0),
    },
    // 7: a floor lamp in the north-east corner.
    Lamp {
        at: (4.45, -3.45, 0.0),
        shade: (0.24, 0.16, 1.45, 0.32),
        radiance: (600.0, 500.0),
    },
    // 8: a reading lamp behind the armchair, bright downwards.
    Lamp {
        at: (1.15, 0.65, 0.0),
        shade: (0.2, 0.14, 1.25, 0.3),
        radiance: (800.0, 300.0),
    },
];

/// A ceiling can: a box 0.3 × 0.3 × 0.25 m under the ceiling, open at the bottom, its emitter
/// (0.2 × 0.2 m, facing down) near its top.
const CAN_HALF: f32 = 0.15;
const CAN_DEPTH: f32 = 0.25;
const CAN_EMITTER_HALF: f32 = 0.1;

/// The cans, `can1` to `can6`: centre (x, z) and radiance (the light colour's brightest
/// channel); 75 to 126 W, the brightest 20 times the dimmest lamp emitter.
const CANS: [(f32, f32, f32); 6] = [
    (-2.6, -1.8, 800.0),
    (0.2, -1.8, 600.0),
    (2.7, -2.4, 1000.0),
    (-2.6, 1.6, 700.0),
    (0.2, 1.6, 600.0),
    (2.9, 1.4, 1000.0),
];

/// The `livingroom` built-in scene.
pub(super) fn livingroom() -> SceneDesc {
    let mut b = Builder::new("livingroom");
    let floor = b.material(MaterialDesc {
        roughness: 0.55,
        ..MaterialDesc::diffuse("floor_wood", Vec3::new(0.42, 0.3, 0.2))
    });
    let wall = b.material(MaterialDesc::diffuse("wall", Vec3::new(0.78, 0.75, 0.7)));
    let ceiling = b.material(MaterialDesc::diffuse("ceiling", Vec3::splat(0.85)));
    room(&mut b, floor, wall, ceiling);
    furniture(&mut b);

    let brass = b.material(MaterialDesc {
        metallic: 1.0,
        roughness: 0.3,
        ..MaterialDesc::diffuse("brass", Vec3::new(0.9, 0.7, 0.35))
    });
    let fabric = b.material(MaterialDesc::diffuse(
        "shade_fabric",
        Vec3::new(0.9, 0.82, 0.66),
    ));
    for (k, lamp) in LAMPS.iter().enumerate() {
        add_lamp(&mut b, k + 1, lamp, brass, fabric);
    }
    let aluminium = b.material(MaterialDesc {
        metallic: 1.0,
        roughness: 0.4,
        ..MaterialDesc::diffuse("can_aluminium", Vec3::splat(0.85))
    });
    for (k, &(x, z, radiance)) in CANS.iter().enumerate() {
        add_can(&mut b, k + 1, (x, z), radiance, aluminium);
    }

    let corners: Vec<Vec3> = WINDOW.iter().map(|p| Vec3::new(p.x, p.y, -D)).collect();
    b.portal("window", ENVIRONMENT_TARGET, &facing(corners, Vec3::Z));
    b.desc.environment = Some(generated_sky(Interpolation::Linear));
    b.camera(Vec3::new(3.7, 1.6, 3.5), Vec3::new(-1.0, 0.9, -1.8), 60.0);
    b.desc
}

/// The floor, the ceiling and four walls, all facing in; the window is a hole in the north wall.
fn room(b: &mut Builder, floor: usize, wall: usize, ceiling: usize) {
    b.flat("floor", floor, &[rect_y(0.0, 0.0, W, D, 0.0, true)]);
    b.flat("ceiling", ceiling, &[rect_y(0.0, 0.0, W, D, H, false)]);
    let mut walls: Vec<Vec<Vec3>> = rectangle_less_hole([-W, W], [0.0, H], &WINDOW)
        .into_iter()
        .map(|piece| {
            let corners = piece.into_iter().map(|p| Vec3::new(p.x, p.y, -D)).collect();
            facing(corners, Vec3::Z)
        })
        .collect();
    let south = vec![
        Vec3::new(-W, 0.0, D),
        Vec3::new(W, 0.0, D),
        Vec3::new(W, H, D),
        Vec3::new(-W, H, D),
    ];
    let west = vec![
        Vec3::new(-W, 0.0, -D),
        Vec3::new(-W, 0.0, D),
        Vec3::new(-W, H, D),
        Vec3::new(-W, H, -D),
    ];
    let east = west.iter().map(|p| Vec3::new(W, p.y, p.z)).collect();
    walls.push(facing(south, -Vec3::Z));
    walls.push(facing(west, Vec3::X));
    walls.push(facing(east, -Vec3::X));
    b.flat("walls", wall, &walls);
}

/// A table: a top from `lo` to `hi` (x, z) at `height`, `thickness` thick, and four square
/// legs of side `leg` inset at its corners.
fn table(lo: Vec2, hi: Vec2, height: f32, thickness: f32, leg: f32) -> Vec<(Vec3, Vec3)> {
    let mut boxes = vec![(
        Vec3::new(lo.x, height - thickness, lo.y),
        Vec3::new(hi.x, height, hi.y),
    )];
    let inset = leg + 0.03;
    for x in [lo.x + inset, hi.x - inset] {
        for z in [lo.y + inset, hi.y - inset] {
            boxes.push((
                Vec3::new(x - 0.5 * leg, 0.0, z - 0.5 * leg),
                Vec3::new(x + 0.5 * leg, height - thickness, z + 0.5 * leg),
            ));
        }
    }
    boxes
}

/// The sofa, the armchair, the tables, the chairs, the bookshelf with its books, the
/// sideboard and the rug.
fn furniture(b: &mut Builder) {
    let v = Vec3::new;
    let rug = b.material(MaterialDesc::diffuse("rug", v(0.5, 0.16, 0.12)));
    b.cuboid("rug", rug, v(-3.9, 0.0, -1.2), v(-0.7, 0.012, 1.2));

    // The sofa faces north, between the side tables.
    let sofa = b.material(MaterialDesc::diffuse("sofa_fabric", v(0.22, 0.3, 0.4)));
    b.cuboids(
        "sofa",
        sofa,
        &[
            (v(-3.4, 0.0, 0.9), v(-1.2, 0.4, 1.8)),
            (v(-3.4, 0.4, 1.55), v(-1.2, 0.88, 1.8)),
            (v(-3.4, 0.4, 0.9), v(-3.2, 0.62, 1.55)),
            (v(-1.4, 0.4, 0.9), v(-1.2, 0.62, 1.55)),
            (v(-3.2, 0.4, 0.95), v(-2.31, 0.48, 1.55)),
            (v(-2.29, 0.4, 0.95), v(-1.4, 0.48, 1.55)),
        ],
    );
    // The armchair faces west, towards the coffee table, in the sun from the window.
    let armchair = b.material(MaterialDesc::diffuse("armchair_fabric", v(0.6, 0.42, 0.12)));
    b.cuboids(
        "armchair",
        armchair,
        &[
            (v(0.0, 0.0, -0.5), v(0.85, 0.4, 0.35)),
            (v(0.65, 0.4, -0.5), v(0.85, 0.85, 0.35)),
            (v(0.0, 0.4, -0.5), v(0.65, 0.6, -0.35)),
            (v(0.0, 0.4, 0.2), v(0.65, 0.6, 0.35)),
        ],
    );

    let wood = b.material(MaterialDesc {
        roughness: 0.4,
        ..MaterialDesc::diffuse("wood", v(0.42, 0.26, 0.14))
    });
    let dark_wood = b.material(MaterialDesc {
        roughness: 0.35,
        ..MaterialDesc::diffuse("dark_wood", v(0.2, 0.12, 0.07))
    });
    let coffee_table = table(
        Vec2::new(-2.8, -0.4),
        Vec2::new(-1.8, 0.2),
        0.42,
        0.04,
        0.05,
    );
    b.cuboids("coffee_table", wood, &coffee_table);
    for (name, x) in [("side_table_west", -3.8), ("side_table_east", -0.8)] {
        let boxes = table(
            Vec2::new(x - 0.25, 1.1),
            Vec2::new(x + 0.25, 1.6),
            0.55,
            0.03,
            0.04,
        );
        b.cuboids(name, wood, &boxes);
    }
    let console = table(
        Vec2::new(-2.15, -3.98),
        Vec2::new(-0.75, -3.55),
        0.8,
        0.04,
        0.04,
    );
    b.cuboids("console_table", dark_wood, &console);

    // The dining table and its four chairs, two on each long side, their backs away from it.
    let dining = table(Vec2::new(1.9, -2.9), Vec2::new(3.5, -1.9), 0.75, 0.04, 0.06);
    b.cuboids("dining_table", dark_wood, &dining);
    let mut chairs = Vec::new();
    for (zc, back) in [(-3.3, -1.0), (-1.5, 1.0)] {
        for xc in [2.3, 3.1] {
            chairs.extend(table(
                Vec2::new(xc - 0.21, zc - 0.21),
                Vec2::new(xc + 0.21, zc + 0.21),
                0.46,
                0.04,
                0.035,
            ));
            let zb = zc + back * 0.195;
            chairs.push((
                v(xc - 0.21, 0.46, zb - 0.015),
                v(xc + 0.21, 0.92, zb + 0.015),
            ));
        }
    }
    b.cuboids("dining_chairs", wood, &chairs);

    // The bookshelf against the west wall: sides, a back, a plinth, shelves and a top.
    let paint = b.material(MaterialDesc {
        roughness: 0.6,
        ..MaterialDesc::diffuse("white_paint", v(0.75, 0.74, 0.7))
    });
    let (x0, x1, z0, z1) = (-4.99, -4.64, -2.9, -1.3);
    let mut shelf = vec![
        (v(x0, 0.0, z0), v(x1, 2.0, z0 + 0.03)),
        (v(x0, 0.0, z1 - 0.03), v(x1, 2.0, z1)),
        (v(x0, 0.0, z0 + 0.03), v(x0 + 0.02, 2.0, z1 - 0.03)),
    ];
    let levels = [0.0, 0.45, 0.85, 1.25, 1.62];
    for (i, y) in levels.into_iter().chain([1.97]).enumerate() {
        let t = if i == 0 { 0.08 } else { 0.03 };
        shelf.push((v(x0 + 0.02, y, z0 + 0.03), v(x1, y + t, z1 - 0.03)));
    }
    b.cuboids("bookshelf", paint, &shelf);
    // Books on every shelf, of three colours, their widths and heights varied by a hash.
    let book_colours = [
        ("books_red", v(0.5, 0.1, 0.08)),
        ("books_green", v(0.12, 0.3, 0.18)),
        ("books_cream", v(0.75, 0.68, 0.5)),
    ];
    let mut books: [Vec<(Vec3, Vec3)>; 3] = Default::default();
    for (s, &y) in levels.iter().enumerate() {
        let y = y + if s == 0 { 0.08 } else { 0.03 };
        let mut z = z0 + 0.05;
        let mut k = 0u32;
        while z < z1 - 0.12 {
            let seed = 97 * s as u32 + k;
            let width = 0.03 + 0.03 * hash01(seed);
            let height = 0.18 + 0.12 * hash01(seed + 1000);
            books[(hash01(seed + 2000) * 3.0) as usize % 3]
                .push((v(x0 + 0.04, y, z), v(x1 - 0.03, y + height, z + width)));
            // Now and then a gap.
            z += width
                + if hash01(seed + 3000) < 0.15 {
                    0.12
                } else {
                    0.003
                };
            k += 1;
        }
    }
    for ((name, colour), boxes) in book_colours.into_iter().zip(&books) {
        let m = b.material(MaterialDesc::diffuse(name, colour));
        b.cuboids(name, m, boxes);
    }

    // The sideboard against the east wall, on a recessed plinth.
    b.cuboids(
        "sideboard",
        paint,
        &[
            (v(4.52, 0.1, -0.6), v(5.0, 0.85, 1.0)),
            (v(4.57, 0.0, -0.55), v(4.97, 0.1, 0.95)),
        ],
    );
}

/// Lamp `k`: its base and stem (`metal`), its shade (`fabric`), the emitters `lamp{k}_down`
/// and `lamp{k}_up` and the portals `lamp{k}_bottom` and `lamp{k}_top` onto them.
fn add_lamp(b: &mut Builder, k: usize, lamp: &Lamp, metal: usize, fabric: usize) {
    let (x, z, y) = lamp.at;
    let (r_bottom, r_top, above, height) = lamp.shade;
    let (y_bottom, y_top) = (y + above, y + above + height);
    let y_mid = 0.5 * (y_bottom + y_top);
    // A floor lamp stands on a wider base with a thicker pole.
    let (base, stem) = if y == 0.0 {
        (0.16, 0.015)
    } else {
        (0.09, 0.012)
    };
    b.cuboid(
        &format!("lamp{k}_base"),
        metal,
        Vec3::new(x - base, y, z - base),
        Vec3::new(x + base, y + 0.03, z + base),
    );
    b.cuboid(
        &format!("lamp{k}_stem"),
        metal,
        Vec3::new(x - stem, y + 0.03, z - stem),
        Vec3::new(x + stem, y_mid - 0.03, z + stem),
    );
    let (bottom, top) = b.shade(fabric, (x, z), (r_bottom, y_bottom), (r_top, y_top), 8, 0.5);
    if let Some(shade) = b.desc.meshes.last_mut() {
        shade.node_name = format!("lamp{k}_shade");
    }
    // The emitters 2 cm apart, their backs to each other, between the two openings.
    let (down, up) = (format!("lamp{k}_down"), format!("lamp{k}_up"));
    let h = LAMP_EMITTER_HALF;
    let (l_down, l_up) = lamp.radiance;
    let m = b.material(MaterialDesc::emitter(&down, WARM * l_down, false));
    b.flat(&down, m, &[rect_y(x, z, h, h, y_mid - 0.01, false)]);
    let m = b.material(MaterialDesc::emitter(&up, WARM * l_up, false));
    b.flat(&up, m, &[rect_y(x, z, h, h, y_mid + 0.01, true)]);
    b.portal(&format!("lamp{k}_bottom"), &down, &bottom);
    b.portal(&format!("lamp{k}_top"), &up, &top);
}

/// Ceiling can `k` centred at (x, z): the box `can{k}` (`material`), its emitter `can{k}_light`
/// and the portal `can{k}_portal` over its open bottom.
fn add_can(b: &mut Builder, k: usize, (x, z): (f32, f32), radiance: f32, material: usize) {
    // Its top 5 mm below the ceiling, so that the two never coincide.
    let (y0, y1) = (H - 0.005 - CAN_DEPTH, H - 0.005);
    let lo = Vec3::new(x - CAN_HALF, y0, z - CAN_HALF);
    let hi = Vec3::new(x + CAN_HALF, y1, z + CAN_HALF);
    // Every face of the box but the bottom (the third, −y).
    let faces: Vec<Vec<Vec3>> = cuboid_faces(lo, hi)
        .into_iter()
        .enumerate()
        .filter_map(|(i, face)| (i != 2).then_some(face))
        .collect();
    b.flat(&format!("can{k}"), material, &faces);
    let light = format!("can{k}_light");
    let m = b.material(MaterialDesc::emitter(&light, NEUTRAL * radiance, false));
    let h = CAN_EMITTER_HALF;
    b.flat(&light, m, &[rect_y(x, z, h, h, y1 - 0.02, false)]);
    let opening = rect_y(x, z, CAN_HALF, CAN_HALF, y0, false);
    b.portal(&format!("can{k}_portal"), &light, &opening);
}
