"""Raw traversal against Mitsuba 3's on the same rays: Mitsuba (`llvm_ad_rgb`, which traces
with Embree) makes a direct-light render's rays on each converted built-in scene, times its own
ray queries on them, and writes them for `portalview bench --only rays`, which times
portalview's traversal on exactly those rays.

Rays: camera rays of a 256x256 image, 16 passes of one sample per pixel in pass-major order
(neighbouring lanes are neighbouring pixels, as in portalview's passes), and for each camera
ray that hits, a shadow ray to a point drawn on the emitters by Mitsuba's own emitter sampling.
Mitsuba's rates: `ray_intersect_preliminary` (the closest hit, no surface interaction) and
`ray_test`, each the fastest of five after a warm-up (JIT compilation). Run with the virtual
environment of `run.sh` and `DRJIT_LIBLLVM_PATH` as there.
"""
import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mitsuba_bench as mb  # noqa: E402

SIZE, PASSES = 256, 16


def fastest(dr, f, rounds=5):
    f()  # warm-up: JIT compilation
    best = float("inf")
    for _ in range(rounds):
        start = time.perf_counter()
        f()
        dr.sync_thread()
        best = min(best, time.perf_counter() - start)
    return best


def write_rays(path, o, d, tmin, tmax):
    """Little-endian f32 records: origin x y z, direction x y z, tmin, tmax."""
    n = len(o[0])
    cols = [*o, *d, np.full(n, tmin), tmax]
    np.stack([np.asarray(c, dtype="<f4") for c in cols], axis=1).tofile(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--portalview", default=str(mb.ROOT / "target/release/portalview"))
    ap.add_argument(
        "--scenes", default="lampshade,fig8a,fig8b,fig8c",
        help="built-in names; NAME+rug adds a rug of a million triangles (mitsuba_bench.add_rug)",
    )
    ap.add_argument("--seconds", type=float, default=2.0, help="portalview's time per measurement")
    ap.add_argument("--keep", type=Path, help="write the scenes and ray files here (kept), for "
                    "`portalview bench --only rays` runs without Mitsuba")
    args = ap.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    n = SIZE * SIZE * PASSES
    print(f"Mitsuba {mi.__version__} llvm_ad_rgb ({dr.thread_count()} threads) against portalview, the same rays")
    print()
    print("portalview's rates: its traversal layout in packets of 8 consecutive rays (as Mitsuba "
          "hands rays to Embree) / one ray at a time / obvhs's traversal one at a time; ratios "
          "to Mitsuba's for the packets")
    print()
    print("| scene | camera rays (Mitsuba: hit) | Mitsuba closest hit Mrays/s | portalview Mrays/s (hit) | ratio | shadow rays (Mitsuba: occluded) | Mitsuba occlusion Mrays/s | portalview Mrays/s (occluded) | ratio |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    with tempfile.TemporaryDirectory(prefix="portalview-rays-") as tmp:
        tmp = args.keep or Path(tmp)
        for name in args.scenes.split(","):
            scene_dir = tmp / name
            scene_dir.mkdir(parents=True, exist_ok=True)
            base, rug = name.removesuffix("+rug"), name.endswith("+rug")
            desc, lambert = mb.convert(mb.ROOT / "assets" / f"{base}.glb", scene_dir, mi, rug)
            scene = mi.load_dict(desc)
            sensor = scene.sensors()[0]
            rng = mi.PCG32(size=n)
            pixel = dr.arange(mi.UInt32, n) % (SIZE * SIZE)
            pos = mi.Point2f((mi.Float(pixel % SIZE) + rng.next_float32()) / SIZE,
                             (mi.Float(pixel // SIZE) + rng.next_float32()) / SIZE)
            camera, _ = sensor.sample_ray(0.0, 0.5, pos, mi.Point2f(0.5))
            si = scene.ray_intersect(camera)
            u = mi.Point2f(rng.next_float32(), rng.next_float32())
            ds, _ = scene.sample_emitter_direction(si, u, False)
            shadow = si.spawn_ray_to(ds.p)
            valid = np.asarray(si.is_valid() & (ds.pdf > 0))
            # Only the shadow rays of camera rays that hit, on both sides.
            o = [np.asarray(c)[valid] for c in (shadow.o.x, shadow.o.y, shadow.o.z)]
            d = [np.asarray(c)[valid] for c in (shadow.d.x, shadow.d.y, shadow.d.z)]
            maxt = np.asarray(shadow.maxt)[valid]
            shadow = mi.Ray3f(mi.Point3f(*o), mi.Vector3f(*d))
            shadow.maxt = mi.Float(maxt)
            cam_o = [np.asarray(c) for c in (camera.o.x, camera.o.y, camera.o.z)]
            cam_d = [np.asarray(c) for c in (camera.d.x, camera.d.y, camera.d.z)]
            write_rays(scene_dir / "camera.rays", cam_o, cam_d, 0.0, np.asarray(camera.maxt))
            write_rays(scene_dir / "shadow.rays", o, d, 0.0, maxt)

            def closest():
                pi = scene.ray_intersect_preliminary(camera)
                dr.eval(pi.t, pi.prim_index)

            def occlusion():
                dr.eval(scene.ray_test(shadow))

            t_closest = fastest(dr, closest)
            t_occlusion = fastest(dr, occlusion)
            hits = int(np.count_nonzero(np.asarray(si.is_valid())))
            occluded = int(np.count_nonzero(np.asarray(scene.ray_test(shadow))))
            out = subprocess.run(
                [args.portalview, "bench", "--only", "rays", "--rays-scene", str(lambert),
                 "--closest-rays", str(scene_dir / "camera.rays"),
                 "--occlusion-rays", str(scene_dir / "shadow.rays"),
                 "--seconds", str(args.seconds)],
                check=True, capture_output=True, text=True,
            ).stdout
            # "KIND[ MODE]: N rays, H hit|occluded, R Mrays/s", KIND closest-hit or occlusion,
            # MODE absent (packets), "one at a time" or "obvhs".
            rates, answers = {}, {}
            for line in out.splitlines():
                kind, _, rest = line.partition(": ")
                if kind.split(" ")[0] in ("closest-hit", "occlusion"):
                    fields = rest.split(", ")
                    answers[kind] = int(fields[1].split()[0])
                    rates[kind] = float(fields[2].split()[0])
            mitsuba = {"closest-hit": n / t_closest / 1e6, "occlusion": len(maxt) / t_occlusion / 1e6}

            def cells(kind):
                ours = "/".join(f"{rates[kind + m]:.1f}" for m in ("", " one at a time", " obvhs"))
                return (f"{mitsuba[kind]:.1f} | {ours} ({answers[kind]}) "
                        f"| {rates[kind] / mitsuba[kind]:.2f}")

            print(f"| {name} | {n} ({hits}) | {cells('closest-hit')} "
                  f"| {len(maxt)} ({occluded}) | {cells('occlusion')} |", flush=True)


if __name__ == "__main__":
    main()
