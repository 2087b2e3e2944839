#!/usr/bin/env python3
"""Two or more portalview builds side by side: the cost of a sample on one thread.

Runs `BIN bench --only tiles` for each build in turn, ROUNDS times (the builds alternate, so
that a slow spell of a shared machine falls on all of them), keeps each build's fastest time
per scene and strategy, and prints them with their ratios to the first build. Speed on this
kind of machine drifts by tens of per cent from run to run; alternated best-of-rounds ratios
move by about one per cent. A change in code layout alone can move a scene by 2-4%, so a
gain below that, or on one scene only, is not one.

    bench/ab_tiles.py --rounds 9 old/portalview new/portalview

Copy each build out of target/ first: building the next one overwrites it.
"""

import argparse
import collections
import re
import subprocess
import sys

ROW = re.compile(r"^\| (\w+) \| (\w+) \| ([0-9.]+) \|", re.M)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("builds", nargs="+", help="portalview binaries; ratios are to the first")
    ap.add_argument("--rounds", type=int, default=9, help="alternated rounds (default 9)")
    ap.add_argument("--size", type=int, default=128, help="image size (default 128)")
    ap.add_argument("--repeats", type=int, default=5, help="renders per tile (default 5)")
    args = ap.parse_args()
    if args.rounds < 1:
        sys.exit("--rounds must be at least 1")

    best = collections.defaultdict(lambda: float("inf"))
    for r in range(args.rounds):
        for b in args.builds:
            cmd = [b, "bench", "--only", "tiles", "--size", str(args.size),
                   "--repeats", str(args.repeats)]
            out = subprocess.run(cmd, capture_output=True, text=True)
            if out.returncode != 0:
                sys.exit(f"{b}: {' '.join(cmd[1:])} failed:\n{out.stderr}")
            rows = ROW.findall(out.stdout)
            if not rows:
                sys.exit(f"{b}: no table in the output of {' '.join(cmd[1:])}")
            for scene, strategy, ns in rows:
                key = (scene, strategy, b)
                best[key] = min(best[key], float(ns))
        print(f"round {r + 1} of {args.rounds} done", file=sys.stderr)

    keys = sorted({(s, st) for s, st, _ in best})
    names = [f"build {i + 1}" for i in range(len(args.builds))]
    print(f"ns per sample, one thread, {args.size}², each build's best of {args.rounds} rounds")
    for i, b in enumerate(args.builds):
        print(f"- build {i + 1}: {b}")
    print()
    head = "| scene | strategy | " + " | ".join(names)
    head += "".join(f" | {n} ÷ build 1" for n in names[1:]) + " |"
    print(head)
    print("|---|---|" + "---:|" * (2 * len(names) - 1))
    for scene, strategy in keys:
        v = [best[(scene, strategy, b)] for b in args.builds]
        cells = " | ".join(f"{x:.1f}" for x in v)
        ratios = "".join(f" | {x / v[0]:.3f}" for x in v[1:])
        print(f"| {scene} | {strategy} | {cells}{ratios} |")


if __name__ == "__main__":
    main()
