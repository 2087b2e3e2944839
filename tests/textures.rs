//! Textures: sampling (wrap modes, filtering, `KHR_texture_transform`, sRGB) against
//! hand-computed values, and rendered scenes against closed forms: a checkerboard floor under
//! a polygon light (per-texel Lambert irradiance), a constant normal map (Lambert irradiance
//! about the tilted normal), a MASK cut-out letting light through, and an emissive texture.
//!
//! Statistical tolerances are 4 standard errors of the estimator (the standard error from the
//! sample variance), each with a negative case showing the comparison can fail.

mod common;

use std::f32::consts::FRAC_PI_2;
use std::sync::Arc;

use glam::{Vec2, Vec3, Vec4};
use portalview::asset::desc::{
    AlphaMode, MaterialDesc, MaterialTextures, MeshDesc, NormalTexture, SceneDesc,
};
use portalview::asset::texture::{
    Encoding, Filter, Image, Sampler, TextureRef, TextureTransform, Wrap, srgb_to_linear,
};
use portalview::light::Strategy;
use portalview::scene::Scene;
use portalview::surface::{SurfaceTextures, bump_shadowing_term, tangent_space_normal};

use common::{camera, flat, floor_radiance, lambert_irradiance, square};

/// A 1 × n image of grey levels, or n × n from `texel(x, y)`.
fn image(width: u32, height: u32, texel: impl Fn(u32, u32) -> [u8; 4]) -> Image {
    let texels = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| texel(x, y))
        .collect();
    Image::new("test".into(), width, height, texels).unwrap()
}

fn grey(v: u8) -> [u8; 4] {
    [v, v, v, 255]
}

fn texture(image: usize) -> TextureRef {
    TextureRef {
        image,
        sampler: Sampler::default(),
        tex_coord: 0,
        transform: None,
    }
}

fn close(a: Vec4, b: Vec4) -> bool {
    (a - b).abs().max_element() < 1e-6
}

#[test]
fn bilinear_filtering_and_wrap_modes_match_hand_computed_values() {
    // Texels 0, 100, 200, 250 (linear /255) in a row of 4.
    let levels = [0u8, 100, 200, 250];
    let img = image(4, 1, |x, _| grey(levels[x as usize]));
    let value = |i: usize| levels[i] as f32 / 255.0;
    let at = |u: f32, wrap: Wrap, filter: Filter| {
        let s = Sampler {
            wrap_s: wrap,
            wrap_t: wrap,
            filter,
        };
        img.sample(Vec2::new(u, 0.5), s, Encoding::Linear).x
    };
    let bilinear = Filter::Bilinear;
    // Texel centres are at (i + 0.5)/4: exact values there.
    for i in 0..4 {
        let u = (i as f32 + 0.5) / 4.0;
        assert!((at(u, Wrap::Repeat, bilinear) - value(i)).abs() < 1e-6);
    }
    // Halfway between texels 1 and 2: their mean.
    assert!((at(0.5, Wrap::Repeat, bilinear) - 0.5 * (value(1) + value(2))).abs() < 1e-6);
    // A quarter of the way from texel 0 to texel 1.
    let u = (0.5 + 0.25) / 4.0;
    assert!((at(u, Wrap::Repeat, bilinear) - (0.75 * value(0) + 0.25 * value(1))).abs() < 1e-6);
    // At u = 0 (the image's left edge) REPEAT blends texel 0 with texel 3, CLAMP keeps
    // texel 0, MIRRORED_REPEAT blends texel 0 with itself.
    assert!((at(0.0, Wrap::Repeat, bilinear) - 0.5 * (value(0) + value(3))).abs() < 1e-6);
    assert!((at(0.0, Wrap::ClampToEdge, bilinear) - value(0)).abs() < 1e-6);
    assert!((at(0.0, Wrap::MirroredRepeat, bilinear) - value(0)).abs() < 1e-6);
    // Outside [0, 1]: REPEAT shifts by whole periods, MIRRORED_REPEAT reflects, CLAMP clamps.
    let u = 1.0 + 1.5 / 4.0;
    assert!((at(u, Wrap::Repeat, bilinear) - value(1)).abs() < 1e-6);
    assert!((at(u, Wrap::MirroredRepeat, bilinear) - value(2)).abs() < 1e-6);
    assert!((at(u, Wrap::ClampToEdge, bilinear) - value(3)).abs() < 1e-6);
    assert!((at(-3.0 + 2.5 / 4.0, Wrap::Repeat, bilinear) - value(2)).abs() < 1e-6);
    assert!((at(-0.6 / 4.0, Wrap::MirroredRepeat, Filter::Nearest) - value(0)).abs() < 1e-6);
    assert!((at(-1.6 / 4.0, Wrap::MirroredRepeat, Filter::Nearest) - value(1)).abs() < 1e-6);
    // Nearest takes the texel the coordinate falls in.
    assert!((at(0.49, Wrap::Repeat, Filter::Nearest) - value(1)).abs() < 1e-6);
    assert!((at(0.51, Wrap::Repeat, Filter::Nearest) - value(2)).abs() < 1e-6);
    // Huge or non-finite coordinates stay in range.
    for u in [1e30, -1e30, f32::NAN, f32::INFINITY] {
        for wrap in [Wrap::Repeat, Wrap::ClampToEdge, Wrap::MirroredRepeat] {
            let v = at(u, wrap, bilinear);
            assert!((0.0..=1.0).contains(&v), "{u} {wrap:?}: {v}");
        }
    }
    // Wrap of integer texel indices.
    assert_eq!(
        (-5..=8)
            .map(|i| Wrap::MirroredRepeat.index(i, 4))
            .collect::<Vec<_>>(),
        vec![3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]
    );
    assert_eq!(Wrap::Repeat.index(-1, 4), 3);
    assert_eq!(Wrap::ClampToEdge.index(-1, 4), 0);
    assert_eq!(Wrap::ClampToEdge.index(9, 4), 3);
    // Bilinear in two dimensions: the centre of a 2 × 2 image is the mean of its texels.
    let square = image(2, 2, |x, y| grey([10, 50, 90, 250][(2 * y + x) as usize]));
    let centre = square.sample(Vec2::splat(0.5), Sampler::default(), Encoding::Linear);
    assert!((centre.x - (10.0 + 50.0 + 90.0 + 250.0) / 4.0 / 255.0).abs() < 1e-6);
    // Row 0 is the top of the image: v = 0.25 reads it.
    let top = square.sample(Vec2::new(0.25, 0.25), Sampler::default(), Encoding::Linear);
    assert!((top.x - 10.0 / 255.0).abs() < 1e-6);
}

#[test]
fn texture_transform_matches_the_extension() {
    let t = |offset: Vec2, rotation: f32, scale: Vec2| TextureTransform {
        offset,
        rotation,
        scale,
    };
    // The extension's first example: the lower-left quadrant rotated clockwise 90°. The
    // corners of the unit square map onto the quadrant [0, 0.5] × [0.5, 1].
    let example = t(Vec2::new(0.0, 1.0), FRAC_PI_2, Vec2::splat(0.5));
    for (uv, expected) in [
        (Vec2::new(0.0, 0.0), Vec2::new(0.0, 1.0)),
        (Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.5)),
        (Vec2::new(1.0, 1.0), Vec2::new(0.5, 0.5)),
        (Vec2::new(0.0, 1.0), Vec2::new(0.5, 1.0)),
    ] {
        let got = example.apply(uv);
        assert!(
            got.abs_diff_eq(expected, 1e-6),
            "{uv} → {got}, expected {expected}"
        );
    }
    // Its second: inverting T, a bottom-left origin.
    let flip = t(Vec2::new(0.0, 1.0), 0.0, Vec2::new(1.0, -1.0));
    assert!(
        flip.apply(Vec2::new(0.3, 0.2))
            .abs_diff_eq(Vec2::new(0.3, 0.8), 1e-6)
    );
    // Scale before rotation before offset.
    let all = t(Vec2::new(0.1, 0.2), 0.3, Vec2::new(2.0, 3.0));
    let uv = Vec2::new(0.4, -0.5);
    let s = uv * Vec2::new(2.0, 3.0);
    let (sin, cos) = 0.3f32.sin_cos();
    let expected = Vec2::new(0.1 + cos * s.x + sin * s.y, 0.2 - sin * s.x + cos * s.y);
    assert!(all.apply(uv).abs_diff_eq(expected, 1e-6));
    // A texture reads its TEXCOORD set, then transforms it.
    let img = Arc::new(image(4, 1, |x, _| grey(60 * x as u8)));
    let texture = portalview::asset::texture::Texture {
        image: img,
        sampler: Sampler {
            filter: Filter::Nearest,
            ..Sampler::default()
        },
        tex_coord: 1,
        transform: Some(t(Vec2::new(0.5, 0.0), 0.0, Vec2::ONE)),
    };
    let uvs = [Vec2::new(0.9, 0.5), Vec2::new(0.1, 0.5)];
    assert!(
        texture
            .coordinate(&uvs)
            .abs_diff_eq(Vec2::new(0.6, 0.5), 1e-6)
    );
    assert!((texture.sample(&uvs, Encoding::Linear).x - 120.0 / 255.0).abs() < 1e-6);
}

#[test]
fn srgb_texels_decode_to_linear() {
    assert_eq!(srgb_to_linear(0.0), 0.0);
    assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
    // Below the curve's knee, a straight line of slope 1/12.92.
    assert!((srgb_to_linear(10.0 / 255.0) - 10.0 / 255.0 / 12.92).abs() < 1e-7);
    // sRGB 128 is 21.6% linear (IEC 61966-2-1).
    assert!((srgb_to_linear(128.0 / 255.0) - 0.215_860_5).abs() < 1e-6);
    // Colours are decoded, alpha is not; data textures are not decoded at all.
    let img = image(1, 1, |_, _| [128, 0, 255, 128]);
    let srgb = img.sample(Vec2::splat(0.5), Sampler::default(), Encoding::Srgb);
    assert!(close(srgb, Vec4::new(0.215_860_5, 0.0, 1.0, 128.0 / 255.0)));
    let linear = img.sample(Vec2::splat(0.5), Sampler::default(), Encoding::Linear);
    assert!(close(
        linear,
        Vec4::new(128.0 / 255.0, 0.0, 1.0, 128.0 / 255.0)
    ));
    // Bilinear filtering interpolates the encoded values and decodes after, as Cycles does
    // (issue 40): between black and white texels that is the decoded mid code value (0.214),
    // not the 0.5 linear that decoding first would give.
    let pair = image(2, 1, |x, _| grey(255 * x as u8));
    let mid = pair.sample(Vec2::splat(0.5), Sampler::default(), Encoding::Srgb);
    assert!((mid.x - srgb_to_linear(0.5)).abs() < 1e-5, "{}", mid.x);
    assert!((mid.x - 0.5).abs() > 0.2);
    // At the texels themselves both orders agree, table or no table.
    for level in [0u8, 1, 10, 128, 200, 255] {
        let one = image(1, 1, |_, _| grey(level));
        let v = one
            .sample(Vec2::splat(0.5), Sampler::default(), Encoding::Srgb)
            .x;
        assert!(
            (v - srgb_to_linear(level as f32 / 255.0)).abs() < 2e-6,
            "{level}: {v}"
        );
    }
}

/// A textured horizontal floor `[-2, 2]²` at y = 0 (texture coordinates `((x + 2)/4,
/// (z + 2)/4)` on both sets), and a square light of radiance `le` facing down above it.
fn textured_floor(material: MaterialDesc, images: Vec<Image>, le: f32) -> (SceneDesc, Vec<Vec3>) {
    let light = square(Vec3::new(0.2, 1.5, -0.1), Vec3::NEG_Y, 0.4);
    let mut floor = flat(
        "floor",
        0,
        &[vec![
            Vec3::new(-2.0, 0.0, -2.0),
            Vec3::new(-2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, 2.0),
            Vec3::new(2.0, 0.0, -2.0),
        ]],
    );
    let uv: Vec<Vec2> = floor
        .positions
        .iter()
        .map(|p| Vec2::new(p.x + 2.0, p.z + 2.0) / 4.0)
        .collect();
    floor.texcoords = [uv.clone(), uv];
    let desc = SceneDesc {
        name: "textured".into(),
        materials: vec![
            material,
            MaterialDesc::emitter("light", Vec3::splat(le), false),
        ],
        meshes: vec![floor, flat("light", 1, std::slice::from_ref(&light))],
        images: images.into_iter().map(Arc::new).collect(),
        camera: camera(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO),
        ..SceneDesc::default()
    };
    (desc, light)
}

/// A Lambertian glTF material (no specular layer) of base colour factor `factor`.
fn lambert(factor: f32, textures: MaterialTextures) -> MaterialDesc {
    MaterialDesc {
        specular_factor: 0.0,
        textures,
        ..MaterialDesc::diffuse("floor", Vec3::splat(factor))
    }
}

/// The floor point at the centre of texel (i, j) of an n × n texture.
fn texel_centre(i: u32, j: u32, n: u32) -> Vec3 {
    let uv = (Vec2::new(i as f32, j as f32) + 0.5) / n as f32;
    Vec3::new(uv.x * 4.0 - 2.0, 0.0, uv.y * 4.0 - 2.0)
}

#[test]
fn checkerboard_floor_matches_per_texel_lambert_irradiance() {
    let (n, le, factor) = (8u32, 4.0f32, 0.9f32);
    let (dark, light_level) = (60u8, 230u8);
    let checker = image(n, n, |x, y| {
        grey(if (x + y) % 2 == 0 { dark } else { light_level })
    });
    let material = lambert(
        factor,
        MaterialTextures {
            base_color: Some(texture(0)),
            ..MaterialTextures::default()
        },
    );
    let (desc, light) = textured_floor(material, vec![checker], le);
    let scene = Scene::from_desc(desc, "checker").unwrap();
    let mut tested = 0;
    for (k, (i, j)) in [(3u32, 3u32), (4, 3), (3, 4), (5, 2), (2, 6), (6, 5)]
        .into_iter()
        .enumerate()
    {
        let x = texel_centre(i, j, n);
        let level = if (i + j) % 2 == 0 { dark } else { light_level };
        let albedo = factor * srgb_to_linear(level as f32 / 255.0);
        let expected = albedo as f64 / std::f64::consts::PI
            * lambert_irradiance(x, Vec3::Y, &light, le) as f64;
        let (mean, se) = floor_radiance(&scene, (Strategy::Light, None), x, 20_000, k as u64);
        assert!(
            (mean - expected).abs() <= 4.0 * se,
            "texel ({i}, {j}): {mean} ± {se} vs Lambert {expected}"
        );
        // Negative case: the other square's albedo, or an undecoded (sRGB-as-linear) texel,
        // is told apart by the same criterion.
        let other = if level == dark { light_level } else { dark };
        let other_albedo = factor * srgb_to_linear(other as f32 / 255.0);
        let undecoded = factor * level as f32 / 255.0;
        for wrong in [other_albedo, undecoded] {
            let wrong = wrong as f64 / std::f64::consts::PI
                * lambert_irradiance(x, Vec3::Y, &light, le) as f64;
            assert!(
                (mean - wrong).abs() > 4.0 * se,
                "texel ({i}, {j}) cannot tell {wrong}"
            );
        }
        tested += 1;
    }
    assert_eq!(tested, 6);
}

/// [`textured_floor`] whose Lambertian floor (albedo `albedo`) has a constant normal map: the
/// tangent-space normal `tilt` quantised to 8 bits. Returns the texel, the scene and the light.
fn normal_mapped_floor(tilt: Vec3, albedo: f32, le: f32) -> ([u8; 4], Scene, Vec<Vec3>) {
    let encode = |v: f32| ((v + 1.0) * 0.5 * 255.0).round() as u8;
    let texel = [encode(tilt.x), encode(tilt.y), encode(tilt.z), 255];
    let material = lambert(
        albedo,
        MaterialTextures {
            normal: Some(NormalTexture {
                texture: texture(0),
                scale: 1.0,
            }),
            ..MaterialTextures::default()
        },
    );
    let (desc, light) = textured_floor(material, vec![image(2, 2, |_, _| texel)], le);
    (texel, Scene::from_desc(desc, "normal").unwrap(), light)
}

#[test]
fn constant_normal_map_tilts_shading_as_expected() {
    let (le, albedo) = (4.0f32, 0.8f32);
    // A constant tangent-space normal tilted 30° towards +u (the tangent), quantised to 8 bits.
    let (texel, scene, light) = normal_mapped_floor(Vec3::new(0.5, 0.0, 0.866), albedo, le);
    // The decoded tangent-space normal; u grows along +x on this floor (MikkTSpace's tangent),
    // so the shading normal tilts towards +x.
    let decoded = tangent_space_normal(Vec4::from_array(texel.map(|c| c as f32 / 255.0)), 1.0);
    let tilted = Vec3::new(decoded.x, decoded.z, 0.0).normalize();
    assert!((tilted.y - 0.866).abs() < 0.01);
    for (k, x) in [Vec3::new(0.6, 0.0, 0.1), Vec3::new(-0.3, 0.0, 0.0)]
        .into_iter()
        .enumerate()
    {
        let expected =
            albedo as f64 / std::f64::consts::PI * lambert_irradiance(x, tilted, &light, le) as f64;
        let flat_expected = albedo as f64 / std::f64::consts::PI
            * lambert_irradiance(x, Vec3::Y, &light, le) as f64;
        let (mean, se) = floor_radiance(&scene, (Strategy::Light, None), x, 20_000, k as u64);
        assert!(
            (mean - expected).abs() <= 4.0 * se,
            "{x}: {mean} ± {se} vs tilted Lambert {expected}"
        );
        // Negative case: the untilted normal, or a tilt the other way, gives other values.
        let mirrored = Vec3::new(-tilted.x, tilted.y, 0.0);
        let other = albedo as f64 / std::f64::consts::PI
            * lambert_irradiance(x, mirrored, &light, le) as f64;
        assert!(
            (mean - flat_expected).abs() > 4.0 * se,
            "{x}: untilted {flat_expected}"
        );
        assert!(
            (mean - other).abs() > 4.0 * se,
            "{x}: mirrored tilt {other}"
        );
    }
    // The tangent frame itself: the bitangent points up the image (decreasing glTF v, -z
    // here), as Blender's does, so a normal tilted towards the image's +Y tilts towards -z.
    let surface = scene.geometry.surfaces[0].as_ref().unwrap();
    let tri = scene
        .geometry
        .triangles
        .iter()
        .find(|t| t.material == 0)
        .unwrap();
    let attributes = scene.geometry.attributes[tri.attributes as usize];
    let point = attributes.at(Vec2::splat(0.3));
    assert!(
        point
            .tangent
            .truncate()
            .normalize()
            .abs_diff_eq(Vec3::X, 1e-5),
        "{}",
        point.tangent
    );
    let mapped = surface.mapped_normal(&point, Vec3::Y).unwrap();
    assert!(
        mapped.abs_diff_eq(Vec3::new(decoded.x, decoded.z, -decoded.y), 1e-5),
        "{mapped}"
    );
    let b = Vec3::Y.cross(Vec3::X) * point.tangent.w;
    assert!(b.abs_diff_eq(Vec3::NEG_Z, 1e-6), "bitangent {b}");
}

/// A normal map tilted 30° toward the image's +Y (green up) under the floor's light: the
/// shading normal tilts up the image, toward decreasing glTF `v` (−z on this floor), as in
/// Blender, and the floor shades as Lambert about that normal (within 4 standard errors), at
/// points from which Cycles' bump shadowing term is 1 over the whole light (checked at its
/// corners: the term's `g` is a ratio of linear functions, extreme at a polygon's vertices),
/// so that the closed form holds. The negative case: the green channel inverted (tilted toward
/// +z, as a DirectX-style map or the earlier flipped bitangent would read it) is rejected.
#[test]
fn a_normal_map_tilted_up_the_image_tilts_as_in_blender() {
    let (le, albedo) = (4.0f32, 0.8f32);
    let (texel, scene, light) = normal_mapped_floor(Vec3::new(0.0, 0.5, 0.866), albedo, le);
    let decoded = tangent_space_normal(Vec4::from_array(texel.map(|c| c as f32 / 255.0)), 1.0);
    // Up the image is −z on this floor (v = (z + 2)/4 grows along +z).
    let up = Vec3::new(decoded.x, decoded.z, -decoded.y).normalize();
    let down = Vec3::new(decoded.x, decoded.z, decoded.y).normalize();
    let lambert_about = |n: Vec3, x: Vec3| {
        albedo as f64 / std::f64::consts::PI * lambert_irradiance(x, n, &light, le) as f64
    };
    for (k, x) in [Vec3::new(0.2, 0.0, 0.3), Vec3::new(0.3, 0.0, 0.35)]
        .into_iter()
        .enumerate()
    {
        for &corner in &light {
            let wi = (corner - x).normalize();
            assert_eq!(bump_shadowing_term(Vec3::Y, up, wi), 1.0, "{x}: {corner}");
        }
        let (mean, se) = floor_radiance(&scene, (Strategy::Light, None), x, 20_000, 30 + k as u64);
        let expected = lambert_about(up, x);
        assert!(
            (mean - expected).abs() <= 4.0 * se,
            "{x}: {mean} ± {se} vs {expected}"
        );
        let inverted = lambert_about(down, x);
        assert!(
            (mean - inverted).abs() > 4.0 * se,
            "{x}: green inverted ({inverted}) is not told apart"
        );
    }
}

#[test]
fn mask_cutout_lets_light_through_the_cut_part() {
    let le = 4.0;
    // An occluder between the light and the floor: a plate at y = 0.75 whose left half
    // (u < 0.5, x < 0) is cut out (alpha 0) and right half is opaque (alpha 1).
    let alpha = image(2, 1, |x, _| [200, 200, 200, if x == 0 { 0 } else { 255 }]);
    let mut plate = flat(
        "plate",
        2,
        &[vec![
            Vec3::new(-3.0, 0.75, -3.0),
            Vec3::new(-3.0, 0.75, 3.0),
            Vec3::new(3.0, 0.75, 3.0),
            Vec3::new(3.0, 0.75, -3.0),
        ]],
    );
    plate.texcoords[0] = plate
        .positions
        .iter()
        .map(|p| Vec2::new(if p.x < 0.0 { 0.0 } else { 1.0 }, 0.5))
        .collect();
    let light = square(Vec3::new(-1.0, 1.5, 0.0), Vec3::NEG_Y, 0.3);
    let desc = |mode: AlphaMode| {
        let floor = flat(
            "floor",
            0,
            &[vec![
                Vec3::new(-5.0, 0.0, -5.0),
                Vec3::new(-5.0, 0.0, 5.0),
                Vec3::new(5.0, 0.0, 5.0),
                Vec3::new(5.0, 0.0, -5.0),
            ]],
        );
        SceneDesc {
            name: "mask".into(),
            materials: vec![
                lambert(0.8, MaterialTextures::default()),
                MaterialDesc::emitter("light", Vec3::splat(le), false),
                MaterialDesc {
                    alpha_mode: mode,
                    textures: MaterialTextures {
                        base_color: Some(TextureRef {
                            sampler: Sampler {
                                filter: Filter::Nearest,
                                wrap_s: Wrap::ClampToEdge,
                                wrap_t: Wrap::ClampToEdge,
                            },
                            ..texture(0)
                        }),
                        ..MaterialTextures::default()
                    },
                    ..MaterialDesc::diffuse("plate", Vec3::ONE)
                },
            ],
            meshes: vec![
                floor,
                flat("light", 1, std::slice::from_ref(&light)),
                plate.clone(),
            ],
            images: vec![Arc::new(alpha.clone())],
            camera: camera(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO),
            ..SceneDesc::default()
        }
    };
    let masked = Scene::from_desc(desc(AlphaMode::Mask { cutoff: 0.5 }), "mask").unwrap();
    let opaque = Scene::from_desc(desc(AlphaMode::Opaque), "opaque").unwrap();
    // Under the cut part: the light's full Lambert irradiance (the plate is absent there).
    let x = Vec3::new(-1.0, 0.0, 0.1);
    let expected = 0.8 / std::f64::consts::PI * lambert_irradiance(x, Vec3::Y, &light, le) as f64;
    // The floor radiance helper looks from just above x: below the plate either way.
    let (mean, se) = floor_radiance(&masked, (Strategy::Light, None), x, 20_000, 3);
    assert!(
        (mean - expected).abs() <= 4.0 * se,
        "{mean} ± {se} vs {expected}"
    );
    // Negative case: with the plate opaque, the same view (which then sees the plate, lit
    // from above, instead of the floor in its shadow) is told apart.
    let (other, other_se) = floor_radiance(&opaque, (Strategy::Light, None), x, 20_000, 3);
    assert!(
        (other - expected).abs() > 4.0 * other_se.max(se),
        "{other} vs {expected}"
    );
    // Camera rays: from above, the cut half shows the floor, the opaque half the plate.
    let down = Vec3::NEG_Y;
    let hit = |scene: &Scene, x: f32| {
        let h = scene
            .geometry
            .bvh
            .closest_hit(Vec3::new(x, 2.0, 0.3), down, 0.0, f32::INFINITY)
            .unwrap();
        scene.geometry.triangles[h.triangle as usize].material
    };
    assert_eq!(hit(&masked, -1.5), 0, "the cut part shows the floor");
    assert_eq!(hit(&masked, 1.5), 2, "the opaque part shows the plate");
    assert_eq!(hit(&opaque, -1.5), 2);
    // Shadow rays likewise.
    let bvh = &masked.geometry.bvh;
    assert!(!bvh.occluded(Vec3::new(-1.5, 0.01, 0.0), Vec3::Y, 0.0, 1.4));
    assert!(bvh.occluded(Vec3::new(1.5, 0.01, 0.0), Vec3::Y, 0.0, 1.4));
}

#[test]
fn blend_coverage_passes_rays_in_proportion_to_alpha() {
    // A plate of uniform alpha 0.25 (BLEND): a quarter of the rays meet it.
    let plate = flat(
        "plate",
        0,
        &[vec![
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(-1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, -1.0),
        ]],
    );
    let desc = SceneDesc {
        name: "blend".into(),
        materials: vec![MaterialDesc {
            alpha: 0.25,
            alpha_mode: AlphaMode::Blend,
            ..MaterialDesc::diffuse("plate", Vec3::ONE)
        }],
        meshes: vec![MeshDesc {
            texcoords: [vec![Vec2::ZERO; 4], Vec::new()],
            ..plate
        }],
        ..SceneDesc::default()
    };
    let scene = Scene::from_desc(desc, "blend").unwrap();
    let mut rng = portalview::sampling::Rng::new(5, 0);
    let n = 20_000;
    let hits = (0..n)
        .filter(|_| {
            let o = Vec3::new(rng.uniform() - 0.5, 1.0, rng.uniform() - 0.5);
            scene.geometry.bvh.occluded(o, Vec3::NEG_Y, 0.0, 2.0)
        })
        .count();
    let p = hits as f64 / n as f64;
    // Binomial standard error of the fraction.
    let se = (0.25 * 0.75 / n as f64).sqrt();
    assert!((p - 0.25).abs() <= 4.0 * se, "{p} vs 0.25 ± {se}");
    assert!((p - 0.3).abs() > 4.0 * se);
}

/// A square light of radiance `le` at height 1.5 facing down whose emissive texture is white
/// on its half x < 0.2 and black on the other (texture coordinates by x), over a Lambertian
/// floor.
fn half_textured_light(le: f32) -> (Scene, Vec<Vec3>) {
    let corners = square(Vec3::new(0.2, 1.5, 0.0), Vec3::NEG_Y, 0.4);
    let mut light = flat("light", 1, std::slice::from_ref(&corners));
    light.texcoords[0] = light
        .positions
        .iter()
        .map(|p| Vec2::new((p.x - 0.2) / 0.8 + 0.5, 0.5))
        .collect();
    let floor = flat(
        "floor",
        0,
        &[vec![
            Vec3::new(-5.0, 0.0, -5.0),
            Vec3::new(-5.0, 0.0, 5.0),
            Vec3::new(5.0, 0.0, 5.0),
            Vec3::new(5.0, 0.0, -5.0),
        ]],
    );
    let emissive = image(2, 1, |x, _| grey(if x == 0 { 255 } else { 0 }));
    let desc = SceneDesc {
        name: "emissive".into(),
        materials: vec![
            lambert(0.8, MaterialTextures::default()),
            MaterialDesc {
                textures: MaterialTextures {
                    emissive: Some(TextureRef {
                        sampler: Sampler {
                            filter: Filter::Nearest,
                            wrap_s: Wrap::ClampToEdge,
                            wrap_t: Wrap::ClampToEdge,
                        },
                        ..texture(0)
                    }),
                    ..MaterialTextures::default()
                },
                ..MaterialDesc::emitter("light", Vec3::splat(le), false)
            },
        ],
        meshes: vec![floor, light],
        images: vec![Arc::new(emissive)],
        camera: camera(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO),
        ..SceneDesc::default()
    };
    let scene = Scene::from_desc(desc, "emissive").unwrap();
    // The lit half as a polygon: x from −0.2 to 0.2.
    let half = corners
        .iter()
        .map(|c| Vec3::new(c.x.min(0.2), c.y, c.z))
        .collect();
    (scene, half)
}

#[test]
fn emissive_texture_shapes_the_light_and_its_image() {
    let le = 5.0;
    let (scene, lit_half) = half_textured_light(le);
    // The emitter seen by camera rays: the texture's colour times the radiance.
    let integrator = portalview::render::integrator::Integrator::new(
        &scene,
        portalview::render::integrator::RenderSettings::default(),
    );
    let mut stats = portalview::render::stats::Stats::default();
    let mut rng = portalview::sampling::Sampler::from(portalview::sampling::Rng::new(1, 1));
    for (x, expected) in [(-0.05, le), (0.45, 0.0)] {
        let l = integrator.radiance(Vec3::new(x, 0.5, 0.05), Vec3::Y, &mut rng, &mut stats);
        assert!((l.x - expected).abs() < 1e-5, "emitter at x = {x}: {l}");
    }
    // Light sampling and BSDF sampling with MIS (the default strategy): the floor sees only
    // the lit half. Its Lambert irradiance, with a negative case for the whole square.
    let whole = square(Vec3::new(0.2, 1.5, 0.0), Vec3::NEG_Y, 0.4);
    for (k, x) in [Vec3::new(0.0, 0.0, 0.2), Vec3::new(0.9, 0.0, -0.3)]
        .into_iter()
        .enumerate()
    {
        let expected =
            0.8 / std::f64::consts::PI * lambert_irradiance(x, Vec3::Y, &lit_half, le) as f64;
        for strategy in [Strategy::Light, Strategy::Antishadow] {
            let (mean, se) = floor_radiance(&scene, (strategy, None), x, 20_000, 10 + k as u64);
            assert!(
                (mean - expected).abs() <= 4.0 * se,
                "{x} {strategy:?}: {mean} ± {se} vs {expected}"
            );
            let untextured =
                0.8 / std::f64::consts::PI * lambert_irradiance(x, Vec3::Y, &whole, le) as f64;
            assert!((mean - untextured).abs() > 4.0 * se);
        }
    }
}

/// Light sampling of a textured emitter draws points uniformly by area (see
/// `docs/method.md`): the density its samples are weighted by is the one the estimator
/// evaluates for the same direction, and the texture only changes the emission there.
#[test]
fn emissive_texture_sample_and_pdf_agree() {
    let (scene, _) = half_textured_light(5.0);
    let light = &scene.geometry.lights[0];
    let sampler = portalview::light::estimator::LightSampler::new(&scene, Strategy::Light, None);
    let surface = scene.geometry.light_surfaces[0].as_ref().unwrap();
    let mut rng = portalview::sampling::Rng::new(3, 3);
    let x = Vec3::new(0.1, 0.0, 0.1);
    let ctx = sampler.context(&scene, 0, x);
    let (mut lit, mut total) = (0, 0);
    for _ in 0..4000 {
        let Some(s) = sampler.sample(&scene, &ctx, rng.uniform(), rng.uniform2()) else {
            continue;
        };
        let (y, dist) = s.hit.unwrap();
        let pdf = sampler.pdf(&scene, &ctx, s.wi, s.hit);
        assert!((pdf - s.pdf).abs() <= 1e-4 * pdf, "{pdf} vs {}", s.pdf);
        let area_pdf = dist * dist / (light.area() * y.n.dot(s.wi).abs());
        assert!((pdf - area_pdf).abs() <= 1e-3 * pdf);
        let scale = surface.emission_scale(y.p);
        let expected = if y.p.x < 0.2 { 1.0 } else { 0.0 };
        if (y.p.x - 0.2).abs() > 1e-3 {
            assert_eq!(scale.x, expected, "at {}", y.p);
        }
        lit += (scale.x > 0.5) as usize;
        total += 1;
    }
    // Uniform by area: half the samples fall on the lit half (binomial, 4 standard errors).
    let fraction = lit as f64 / total as f64;
    assert!(
        (fraction - 0.5).abs() <= 4.0 * (0.25 / total as f64).sqrt(),
        "{fraction}"
    );
}

#[test]
fn surface_textures_name_a_missing_image() {
    let material = lambert(
        0.5,
        MaterialTextures {
            base_color: Some(texture(3)),
            ..MaterialTextures::default()
        },
    );
    let Err(e) = SurfaceTextures::new(&material, &[]) else {
        panic!("a texture without its image must be refused");
    };
    let message = e.to_string();
    assert!(
        message.contains("floor") && message.contains("baseColorTexture") && message.contains('3'),
        "{message}"
    );
}
