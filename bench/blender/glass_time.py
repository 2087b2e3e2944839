"""Equal-time convergence of thin glass (issue 38): Cycles against portalview on glass.py's scenes.

Run with Blender 3.4 from the repository root after glass.py has made --out (scene.glb, masks,
Cycles' "thin" and "glass" references), on an otherwise idle machine:

    blender -b --factory-startup -P bench/blender/glass_time.py -- --scene pane_room|globe \
        [--out /tmp/glass-check/<scene>] [--depths 1] [--spps 16,64,256,1024] \
        [--variants glass,thin] [--portalview target/release/portalview] [--ref-spp 2048]

Error is measured on glass.py's `room` region (pane_room: pixels that see no sky through the
openings; globe: neither the globe nor the bare bulb), in luminance:
MSE - floor against a reference, relMSE = (MSE - floor) / mean(reference)^2, efficiency
1 / ((MSE - floor) x seconds).

- The reference (the glTF thin-walled model): portalview (seeds 101, 102, --ref-spp each) and
  Cycles' "thin" renders from glass.py (seeds 1, 2), each pair averaged, the two averages mixed
  by inverse variance. A pair's floor (the MSE of its average) is mean((a - b)^2) / 4; the
  mix's is w^2 f_pv + (1 - w)^2 f_cy. Their difference, against f_pv + f_cy, checks that the
  two agree.
- Cycles, seed 11, at each of --spps: "glass" (the Principled glass as exported, glass.py's
  settings: shadow rays stop at it) and "thin" (glass.py's glTF-thin rendition: Transparent
  BSDF, shadow rays pass, Cycles portals in pane_room's windows). Time: the wall time of
  bpy.ops.render.render (scene sync included) and its sampling part (from the first
  render_stats report of a sample to the end). Cycles' Principled glass is not the thin model
  (exact Fresnel and the pane's inter-reflections: pane_room's room pixels differ by an MSE of
  ~5e-7 at d 1), so "glass" is also measured against its own converged image, glass.py's two
  4096-spp seeds ("own"), with that pair's floor.
- portalview, seed 11, `--seconds` = each Cycles "glass" render's sampling time (or
  --pv-seconds), RAYON_NUM_THREADS = --pv-threads; time = its reported pass time (scene load
  excluded, like Cycles' sampling time). At the longest, once more with --glass-shadows stop.

Prints a table per depth and writes time-report.json to --out. The time portalview needs to
reach Cycles' error at its largest spp is (MSE - floor) x seconds, the median over portalview's
runs, divided by Cycles' MSE - floor.
"""

import math
import os
import re
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import load_exr, luminance, render_cycles, run_portalview, script_argv, write_json  # noqa: E402
from glass import (  # noqa: E402
    build, cycles_bounces, cycles_variant, depth_limit, parser, region_masks,
)

SEED = 11
REF_SEEDS = (101, 102)


def args():
    p = parser()
    p.set_defaults(portalview="target/release/portalview", depths="1")
    p.add_argument("--spps", default="16,64,256,1024", help="Cycles samples per pixel")
    p.add_argument("--variants", default="glass,thin", help="Cycles variants to time")
    p.add_argument("--ref-spp", type=int, default=2048, help="portalview reference spp per seed")
    p.add_argument("--pv-seconds", default="", help="portalview budgets (default: Cycles glass')")
    p.add_argument("--reference-only", action="store_true")
    return p.parse_args(script_argv())


def pair(paths):
    """The average of two renders' luminance and its floor over `m` (applied later):
    returns (average, per-pixel (a - b)^2 / 4)."""
    a, b = (luminance(load_exr(p)) for p in paths)
    return (a + b) / 2, (a - b) ** 2 / 4


def reference(a, out, d, m):
    """The thin model's reference for depth d over mask m: (image, floor, info)."""
    tdir = os.path.join(out, "time")
    pv_paths = [os.path.join(tdir, f"ref-pv-d{d}-{s}.exr") for s in REF_SEEDS]
    spp = a.pv_spp
    a.pv_spp = a.ref_spp
    for s, p in zip(REF_SEEDS, pv_paths):
        if not os.path.exists(p):
            run_portalview(a.portalview, os.path.join(out, "scene.glb"), p, a, seed=s, depth=d)
    a.pv_spp = spp
    pv, pv_n = pair(pv_paths)
    cy, cy_n = pair([os.path.join(out, f"cycles-thin-d{d}-{s}.exr") for s in (1, 2)])
    f_pv, f_cy = float(pv_n[m].mean()), float(cy_n[m].mean())
    w = f_cy / (f_pv + f_cy)
    ref = w * pv + (1 - w) * cy
    floor = w * w * f_pv + (1 - w) ** 2 * f_cy
    diff = float(((pv - cy)[m] ** 2).mean())
    info = {"portalview_floor": f_pv, "cycles_thin_floor": f_cy, "portalview_weight": w,
            "floor": floor, "mean": float(ref[m].mean()),
            "pv_vs_thin_mse": diff, "pv_vs_thin_expected": f_pv + f_cy}
    print(f"reference d{d}: portalview {a.ref_spp} spp x 2 (floor {f_pv:.3g}), Cycles thin x 2 "
          f"(floor {f_cy:.3g}), weight {w:.2f} -> floor {floor:.3g}; their MSE {diff:.3g} "
          f"(noise alone {f_pv + f_cy:.3g}); mean {info['mean']:.4g}")
    return ref, floor, info


def cycles_timed(path, spp, d, transparent, threads):
    """A Cycles render (seed SEED) timed: (seconds of sampling, wall seconds of the render,
    Cycles' own total "Time:"). Blender's stdout is read for Cycles' status lines: sampling runs
    from the first line reporting a sample to the last line."""
    log = path + ".log"
    sys.stdout.flush()
    saved = os.dup(1)
    with open(log, "w") as f:
        os.dup2(f.fileno(), 1)
        try:
            t0 = time.perf_counter()
            render_cycles(path, spp, SEED, threads=threads,
                          overrides=cycles_bounces(d, transparent))
            wall = time.perf_counter() - t0
        finally:
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)
    stamps = []  # (Cycles' Time:, line reports a sample)
    for line in open(log):
        t = re.search(r"Time:(\d+):(\d+\.\d+)", line)
        if t:
            stamps.append((60 * float(t[1]) + float(t[2]), "Sample " in line))
    first = next((t for t, sample in stamps if sample), float("nan"))
    return stamps[-1][0] - first, wall, stamps[-1][0]


def error(img, ref, floor, m):
    mse = float(((img - ref)[m] ** 2).mean()) - floor
    return mse, mse / float(ref[m].mean()) ** 2


def main():
    a = args()
    out = os.path.abspath(a.out or f"/tmp/glass-check/{a.scene}")
    tdir = os.path.join(out, "time")
    os.makedirs(tdir, exist_ok=True)
    glb = os.path.join(out, "scene.glb")
    build(a, out)
    m = region_masks(a, out)["room"]
    report = {"scene": a.scene, "args": vars(a), "room_pixels": int(m.sum()), "depths": {}}
    for d in (int(x) for x in a.depths.split(",")):
        ref, floor, info = reference(a, out, d, m)
        rep = report["depths"][f"d{d}"] = {"reference": info, "rows": []}
        if a.reference_only:
            continue
        own, own_n = pair([os.path.join(out, f"cycles-glass-d{d}-{s}.exr") for s in (1, 2)])
        own_floor = float(own_n[m].mean())
        rows = rep["rows"]
        for variant in a.variants.split(","):
            transparent = cycles_variant(a, out, variant)
            depth_limit(d)
            for spp in (int(x) for x in a.spps.split(",")):
                path = os.path.join(tdir, f"cycles-{variant}-d{d}-{spp}.exr")
                sampling, wall, own_time = cycles_timed(path, spp, d, transparent, a.threads)
                img = luminance(load_exr(path))
                mse, rel = error(img, ref, floor, m)
                row = {"renderer": f"Cycles {variant}", "spp": spp, "seconds": sampling,
                       "wall": wall, "cycles_time": own_time, "mse": mse, "relmse": rel}
                if variant == "glass":
                    row["mse_own"], row["relmse_own"] = error(img, own, own_floor, m)
                rows.append(row)
                print(f"  Cycles {variant} {spp} spp: {sampling:.2f} s sampling ({wall:.2f} s "
                      f"render, Cycles {own_time:.2f} s), MSE-floor {mse:.3g}", flush=True)
        budgets = ([float(x) for x in a.pv_seconds.split(",")] if a.pv_seconds else
                   [r["seconds"] for r in rows if r["renderer"] == "Cycles glass"])
        runs = [(t, "pass") for t in budgets] + [(max(budgets), "stop")]
        for t, glass in runs:
            path = os.path.join(tdir, f"pv-d{d}-{glass}-{t:.3g}s.exr")
            run = {}
            img = run_portalview(a.portalview, glb, path, a, seed=SEED, depth=d, seconds=t,
                                 extra=["--glass-shadows", glass], info=run)
            spp, secs = re.search(r"(\d+) spp in ([\d.]+) s", run["stdout"]).groups()
            mse, rel = error(img, ref, floor, m)
            rows.append({"renderer": f"portalview {glass}", "spp": int(spp),
                         "seconds": float(secs), "wall": run["wall"], "mse": mse,
                         "relmse": rel})
        for r in rows:
            r["efficiency"] = 1 / (r["mse"] * r["seconds"]) if r["mse"] > 0 else float("inf")
        pv = [r for r in rows if r["renderer"] == "portalview pass"]
        c = float(np.median([r["mse"] * r["seconds"] for r in pv]))
        e_pv = float(np.median([r["efficiency"] for r in pv]))
        print(f"\n{a.scene} d{d}: room {int(m.sum())} px, reference mean {info['mean']:.4g}, "
              f"floor {floor:.3g}")
        print(f"{'renderer':<17} {'spp':>6} {'seconds':>8} {'wall':>7} {'MSE-floor':>10} "
              f"{'relMSE':>9} {'efficiency':>11} {'vs own':>9}")
        for r in rows:
            o = f"{r['mse_own']:9.3g}" if "mse_own" in r else ""
            print(f"{r['renderer']:<17} {r['spp']:6d} {r['seconds']:8.2f} {r['wall']:7.2f} "
                  f"{r['mse']:10.3g} {r['relmse']:9.3g} {r['efficiency']:11.4g} {o}")
        for variant in a.variants.split(","):
            cy = [r for r in rows if r["renderer"] == f"Cycles {variant}"]
            last = cy[-1]
            key = "mse_own" if variant == "glass" else "mse"
            e_cy = 1 / (last[key] * last["seconds"])
            summary = {"cycles_spp": last["spp"], "cycles_seconds": last["seconds"],
                       "cycles_mse": last[key], "portalview_seconds_to_it": c / last[key],
                       "efficiency_ratio": e_pv / e_cy}
            rep[f"vs_{variant}"] = summary
            print(f"Cycles {variant} ({'own reference' if key == 'mse_own' else 'thin reference'})"
                  f" at {last['spp']} spp: MSE {last[key]:.3g} in {last['seconds']:.1f} s; "
                  f"portalview reaches it in {c / last[key]:.3g} s; efficiency ratio "
                  f"portalview / Cycles {e_pv / e_cy:.3g}")
    write_json(os.path.join(out, "time-report.json"), report)
    print("wrote", os.path.join(out, "time-report.json"))


if __name__ == "__main__":
    main()
