#!/usr/bin/env python3
"""Where a sample's time goes: a `perf` profile of one render, by the part of the code it is in.

The tile renderer inlines a whole path into one function per instruction set, so `perf report`
by symbol says nothing. This script records `portalview render` on one thread
(RAYON_NUM_THREADS=1), resolves every sampled address with `addr2line -i` (the release build
has debug info), and charges the sample to the innermost inlined frame that lies in
portalview's own `src/`, by folder: the traversal (`scene/bvh`), the light's selection and
sampling (`light/`), the warps and polygons (`sampling/`, without Sobol'), Sobol' numbers
(`sampling/sobol.rs`), the BSDF (`material/`, `surface.rs`), textures, the path loop
(`render/integrator.rs`), the staged schedule's first vertices in lanes
(`render/integrator/packet.rs`, `sampling/lanes.rs`) and shadow queue (`render/shadows.rs`),
the continuation, the tile loop with the camera, and the film.
Scene set-up runs on the main thread and is left out.

    python3 bench/profile.py target/release/portalview --scene fig8a --strategy light

Needs `perf` (Debian: linux-perf) and `addr2line` (binutils).
"""

import argparse
import collections
import os
import re
import subprocess
import tempfile

PARTS = [
    ("/scene/bvh/", "rays (traversal)"),
    ("/sampling/sobol.rs", "random numbers (Sobol')"),
    ("/sampling/lanes.rs", "first vertices in lanes (render/integrator/packet.rs)"),
    ("/render/integrator/packet.rs", "first vertices in lanes (render/integrator/packet.rs)"),
    ("/sampling/", "warps, polygons (sampling/)"),
    ("/light/", "light selection and sampling (light/)"),
    ("/material/", "BSDF"),
    ("/surface.rs", "BSDF"),
    ("/asset/texture", "textures"),
    ("/render/continuation.rs", "BSDF sampling (continuation)"),
    ("/render/shadows.rs", "shadow queue (staged schedule)"),
    ("/render/integrator.rs", "path loop (integrator)"),
    ("/render/stats.rs", "path loop (integrator)"),
    ("/render/film.rs", "film"),
    ("/render/mod.rs", "tile loop, camera"),
    ("/camera.rs", "tile loop, camera"),
]


def part(location):
    for key, name in PARTS:
        if key in location:
            return name
    return None


def text_bias(binary):
    """Virtual address minus file offset of the executable segment."""
    out = subprocess.run(["readelf", "-lW", binary], capture_output=True, text=True,
                         check=True).stdout
    for line in out.splitlines():
        f = line.split()
        if f and f[0] == "LOAD" and "E" in f[6:-1]:
            return int(f[2], 16) - int(f[1], 16)
    raise SystemExit(f"{binary}: no executable LOAD segment")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("binary")
    ap.add_argument("--scene", default="fig8a")
    ap.add_argument("--strategy", default="light")
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--max-depth", type=int, default=1)
    args = ap.parse_args()
    binary = os.path.realpath(args.binary)
    work = tempfile.mkdtemp(prefix="pv-profile-")
    data = os.path.join(work, "perf.data")
    subprocess.run(
        ["perf", "record", "-F", "4000", "-o", data, binary, "render", "--scene", args.scene,
         "--strategy", args.strategy, "--spp", str(args.spp), "--width", str(args.width),
         "--max-depth", str(args.max_depth), "--out", os.path.join(work, "image.exr")],
        env=dict(os.environ, RAYON_NUM_THREADS="1"), check=True,
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    script = subprocess.run(["perf", "script", "-i", data, "--show-mmap-events", "-F",
                             "tid,ip,dso"], capture_output=True, text=True, check=True).stdout
    mapping = re.compile(r"\[(0x[0-9a-f]+)\((0x[0-9a-f]+)\) @ (0x[0-9a-f]+) .*r-xp " +
                         re.escape(binary) + "$")
    start = size = pgoff = None
    samples = []
    for line in script.splitlines():
        if "PERF_RECORD_MMAP" in line:
            m = mapping.search(line)
            if m and start is None:
                start, size, pgoff = (int(g, 16) for g in m.groups())
            continue
        f = line.split()
        if len(f) >= 3:
            samples.append((f[0], int(f[1], 16), f[2]))
    if start is None:
        raise SystemExit("the binary's text mapping was not recorded")
    # The render's tiles run on the one rayon thread: the thread with the most samples.
    tid = collections.Counter(s[0] for s in samples).most_common(1)[0][0]
    bias = text_bias(binary)
    counts = collections.Counter()
    total = 0
    for t, ip, _ in samples:
        if t != tid:
            continue
        total += 1
        if start <= ip < start + size:
            counts[ip - start + pgoff + bias] += 1
    addresses = sorted(counts)
    # `0x0` after each address marks where its inline chain ends (it resolves to ?? / ??:0).
    query = "".join(f"0x{a:x}\n0x0\n" for a in addresses)
    lines = subprocess.run(["addr2line", "-i", "-f", "-C", "-e", binary], input=query,
                           capture_output=True, text=True, check=True).stdout.splitlines()
    chains, chain = [], []
    for function, location in zip(lines[0::2], lines[1::2]):
        if function == "??" and location.startswith("??:"):
            chains.append(chain)
            chain = []
        else:
            chain.append(location)
    parts = collections.Counter()
    for address, chain in zip(addresses, chains):
        found = next((p for p in map(part, chain) if p), "elsewhere (std, libm, glam)")
        parts[found] += counts[address]
    parts["outside the binary (kernel, libc)"] += total - sum(counts.values())
    print(f"{args.scene}, {args.strategy}, depth {args.max_depth}: {total} samples on one thread")
    print("| part | share |\n|---|---:|")
    for name, n in parts.most_common():
        print(f"| {name} | {100 * n / total:.1f}% |")


if __name__ == "__main__":
    main()
