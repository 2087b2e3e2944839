#!/usr/bin/env python3
"""What a pane costs antishadow: `panes` against `windows2` (the same room without its panes).

For each build in turn, each round, runs `compare --scene panes` and `--scene windows2`
(antishadow, 128 px wide, 5 s, 3 seeds, the 120 s references `compare` caches) and prints, per
build and round, the efficiency of `panes` over `windows2`, efficiency being
1 / (relMSE x seconds): relative, since the glass makes the image about 8% darker. The builds
alternate, so a slow spell of this shared machine falls on all of them; compare builds within
one run.

    python3 bench/pane_cost.py --rounds 3 old/portalview new/portalview
"""

import argparse
import pathlib
import statistics
import subprocess
import tempfile


def efficiencies(out):
    """Antishadow's 1 / (relMSE x seconds) for each seed of one `compare --out` directory."""
    values = []
    for summary in sorted(pathlib.Path(out).glob("seed-*/summary.md")):
        columns = None
        for line in summary.read_text().splitlines():
            cells = [c.strip() for c in line.split("|")]
            if line.startswith("| strategy"):
                columns = {name: i for i, name in enumerate(cells)}
            elif line.startswith("| antishadow") and columns:
                seconds = float(cells[columns["seconds"]])
                relmse = float(cells[columns["relMSE"]])
                values.append(1.0 / (relmse * seconds))
    if not values:
        raise SystemExit(f"no antishadow rows under {out}")
    return values


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("builds", nargs="+", help="portalview binaries")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--seconds", type=float, default=5)
    args = ap.parse_args()
    work = pathlib.Path(tempfile.mkdtemp(prefix="pane-cost-"))
    ratios = {b: [] for b in args.builds}
    for round_ in range(args.rounds):
        seed = 43 + 3 * round_
        for b, build in enumerate(args.builds):
            mean = {}
            for scene in ("panes", "windows2"):
                out = work / f"{b}-{scene}-{round_}"
                subprocess.run(
                    [build, "compare", "--scene", scene, "--strategies", "antishadow",
                     "--seconds", str(args.seconds), "--width", "128", "--seed", str(seed),
                     "--runs", "3", "--reference-seconds", "120", "--out", str(out)],
                    check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                mean[scene] = statistics.mean(efficiencies(out))
            ratios[build].append(mean["panes"] / mean["windows2"])
    print("| build | panes over windows2, per round | mean | a pane's cost |")
    print("|---|---|---:|---:|")
    for build, r in ratios.items():
        each = ", ".join(f"{x:.3f}" for x in r)
        m = statistics.mean(r)
        print(f"| {build} | {each} | {m:.3f} | {100 * (1 - m):.0f}% |")


if __name__ == "__main__":
    main()
