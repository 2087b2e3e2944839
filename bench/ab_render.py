#!/usr/bin/env python3
"""Two or more portalview builds side by side on any scene: samples per second on one thread.

`bench/ab_tiles.py` times the built-in scenes through `bench --only tiles`; this one times
`BIN render` on the scenes given (built-in names or `.glb` files, such as the Lambertian copies
that `bench/peers/run.sh rays --keep DIR` leaves in `DIR/NAME/NAME-lambert.glb`), so that
builds can be compared on the peer benchmark's own scenes. The builds alternate, ROUNDS times, and each keeps its fastest
samples/s (as `render` reports it, set-up excluded) per scene and strategy; ratios are to the
first build. An environment variable for one build goes in a wrapper script.

    bench/ab_render.py --rounds 3 --scenes a.glb,b.glb old/portalview new/portalview

Copy each build out of target/ first: building the next one overwrites it.
"""

import argparse
import collections
import os
import re
import subprocess
import sys
import tempfile

RATE = re.compile(r"([0-9.]+) M samples/s")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("builds", nargs="+", help="portalview binaries; ratios are to the first")
    ap.add_argument("--scenes", required=True, help="comma-separated built-ins or .glb files")
    ap.add_argument("--strategies", default="light,antishadow")
    ap.add_argument("--rounds", type=int, default=3, help="alternated rounds (default 3)")
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--max-depth", type=int, default=1)
    args = ap.parse_args()
    if args.rounds < 1:
        sys.exit("--rounds must be at least 1")
    scenes = args.scenes.split(",")
    strategies = args.strategies.split(",")
    best = collections.defaultdict(float)
    out = os.path.join(tempfile.mkdtemp(prefix="pv-ab-"), "image.exr")
    env = dict(os.environ, RAYON_NUM_THREADS="1")
    for _ in range(args.rounds):
        for scene in scenes:
            for strategy in strategies:
                for b in args.builds:
                    cmd = [b, "render", "--scene", scene, "--strategy", strategy,
                           "--spp", str(args.spp), "--width", str(args.width),
                           "--max-depth", str(args.max_depth), "--out", out]
                    run = subprocess.run(cmd, capture_output=True, text=True, env=env)
                    m = RATE.search(run.stdout)
                    if run.returncode != 0 or not m:
                        sys.exit(f"{' '.join(cmd)} failed:\n{run.stdout}{run.stderr}")
                    key = (scene, strategy, b)
                    best[key] = max(best[key], float(m.group(1)))
    names = " | ".join(f"build {i + 1} M samples/s" for i in range(len(args.builds)))
    ratios = " | ".join(f"{i + 1} ÷ 1" for i in range(1, len(args.builds)))
    print(f"| scene | strategy | {names} | {ratios} |")
    print("|---|---|" + "---:|" * (2 * len(args.builds) - 1))
    for scene in scenes:
        for strategy in strategies:
            rates = [best[(scene, strategy, b)] for b in args.builds]
            cells = " | ".join(f"{r:.3f}" for r in rates)
            ratio = " | ".join(f"{r / rates[0]:.3f}" for r in rates[1:])
            print(f"| {os.path.basename(scene)} | {strategy} | {cells} | {ratio} |")


if __name__ == "__main__":
    main()
