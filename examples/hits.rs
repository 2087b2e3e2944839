// scratch: share of guided and env draws that find the sun from sunlit floor points
use glam::{Vec2, Vec3};
use portalview::light::LightSet;
use portalview::light::Strategy;
use portalview::light::sky::SkySampler;
use portalview::sampling::Rng;
fn main() {
    let scene = portalview::scene::Scene::open("window").unwrap();
    let sun = portalview::asset::builtin::sky_sun_direction();
    for x in [
        Vec3::new(-0.9, 0.001, 1.2),
        Vec3::new(-1.2, 0.001, 1.5),
        Vec3::new(-0.2, 0.001, -0.3),
    ] {
        let w = &scene.windows()[0];
        if w.through(x, sun).is_none() {
            println!("{x}: sun not through window");
            continue;
        }
        for strategy in [Strategy::Light, Strategy::Antishadow] {
            let s = SkySampler::new(&scene, strategy, None);
            let ctx = s.context(&scene, x);
            let mut rng = Rng::new(1, 2);
            let n = 200_000;
            let (mut hits, mut sum, mut sum2) = (0, 0.0f64, 0.0f64);
            for _ in 0..n {
                let v = match s.sample(&scene, &ctx, rng.uniform(), rng.uniform2()) {
                    Some(smp) => {
                        if smp.le.x > 100.0 {
                            hits += 1;
                        }
                        let c = smp.wi.y.max(0.0) * f32::from(w.through(x, smp.wi).is_some());
                        (smp.le.x * c / smp.pdf) as f64
                    }
                    None => 0.0,
                };
                sum += v;
                sum2 += v * v;
            }
            let m = sum / n as f64;
            println!(
                "{x} {}: hits {:.4} mean {m:.3} relvar {:.4}",
                strategy.name(),
                hits as f64 / n as f64,
                sum2 / n as f64 / (m * m) - 1.0
            );
        }
    }
    let _ = Vec2::ZERO;
}
