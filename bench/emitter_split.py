#!/usr/bin/env python3
"""How much of a render's error lies where the camera looks at a lit emitter or into its enclosure.

Where the camera looks into a can or a shade (its inner walls next to the emitter hundreds of
times brighter than the room) the image is far brighter than elsewhere, and so is its noise.
This script splits each image's squared error against the reference into those pixels (the
reference's mean over RGB above --threshold, grown by one pixel) and the rest, so that what a
change does to the room is not hidden by what it does not do there.

    python3 bench/emitter_split.py REFERENCE.exr IMAGE.exr [IMAGE.exr ...] --threshold 3

REFERENCE is what `portalview compare` caches (`~/.cache/portalview/<scene>-<hash>.exr`, named
in its summary.md); the images are `portalview render ... --out IMAGE.exr` at the reference's
size. Needs numpy and OpenEXR (`pip install numpy OpenEXR`).
"""

import argparse

import numpy as np
import OpenEXR


def load(path):
    """An OpenEXR's RGB as float64 (h, w, 3)."""
    channels = OpenEXR.File(path).channels()
    if "RGB" in channels:
        return channels["RGB"].pixels.astype(np.float64)
    return np.stack([channels[c].pixels for c in "RGB"], -1).astype(np.float64)


def near_emitters(reference, threshold):
    """Pixels whose reference mean exceeds `threshold`, and their eight neighbours."""
    hot = reference.mean(-1) > threshold
    grown = hot.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            grown |= np.roll(np.roll(hot, dy, 0), dx, 1)
    return grown


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("reference")
    ap.add_argument("images", nargs="+")
    ap.add_argument("--threshold", type=float, default=3.0, help="the reference's radiance")
    a = ap.parse_args()
    reference = load(a.reference)
    near = near_emitters(reference, a.threshold)
    print(f"pixels above {a.threshold:g} (and beside them): {100 * near.mean():.2f}%")
    print("| image | MSE | share in those pixels | MSE elsewhere |")
    print("|---|---:|---:|---:|")
    for path in a.images:
        error = ((load(path) - reference) ** 2).mean(-1)
        share = error[near].sum() / error.sum()
        print(f"| {path} | {error.mean():.3e} | {100 * share:.1f}% | {error[~near].mean():.3e} |")


main()
