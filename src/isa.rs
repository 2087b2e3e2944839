//! The instruction sets the renderer is compiled for, and the one this CPU runs: the tile
//! renderer (`render::render_tile_scheduled`) and the BVH's node test (`scene::bvh`) both
//! follow it.

/// The instruction sets the tile renderer is compiled for. One build runs on any x86-64: the
/// renderer (traversal, shading and sampling, all inlined into it) is compiled once per variant,
/// and the best variant the CPU runs is chosen at run time. All give the same pixels, bit for
/// bit: Rust never fuses a multiply and an add unless asked (`mul_add`, correctly rounded
/// either way), and the wider instructions compute the same IEEE operations. The BVH's node
/// test follows the same choice (`scene::bvh::node_hits`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Isa {
    /// The target's baseline (SSE2 on x86-64).
    Baseline,
    /// x86-64-v3: AVX2, FMA, BMI1/2, LZCNT and POPCNT (the BVH traversal counts and scans bits).
    /// An AVX-512 (x86-64-v4) variant measured 7–12% slower than this one and was dropped.
    Avx2,
}

impl Isa {
    pub const ALL: [Isa; 2] = [Isa::Baseline, Isa::Avx2];

    /// The best variant this CPU runs, chosen once. `PORTALVIEW_ISA=baseline` in the environment
    /// forces the baseline (to measure what the dispatch gains).
    pub fn detect() -> Isa {
        static DETECTED: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *DETECTED.get_or_init(|| {
            let forced = std::env::var("PORTALVIEW_ISA").is_ok_and(|v| v == Isa::Baseline.name());
            if !forced && Isa::Avx2.available() {
                Isa::Avx2
            } else {
                Isa::Baseline
            }
        })
    }

    /// Whether this CPU can run the variant.
    pub fn available(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            match self {
                Isa::Baseline => true,
                Isa::Avx2 => {
                    has!("avx2")
                        && has!("fma")
                        && has!("bmi1")
                        && has!("bmi2")
                        && has!("lzcnt")
                        && has!("popcnt")
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self == Isa::Baseline
        }
    }

    /// As `PORTALVIEW_ISA` names it.
    pub fn name(self) -> &'static str {
        match self {
            Isa::Baseline => "baseline",
            Isa::Avx2 => "avx2",
        }
    }
}
