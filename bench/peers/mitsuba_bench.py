#!/usr/bin/env python3
"""portalview against Mitsuba 3 (`llvm_ad_rgb`) on the built-in scenes, in one run.

For each `assets/*.glb` named in `--scenes` (`NAME+rug`: with a rug of a million triangles on
its floor, `add_rug`, so that rays cost more) this script
  1. converts the scene: every mesh to a PLY in world space, every material to a Lambertian
     `diffuse` in `twosided` (of the base colour, also for metals), every emissive material
     to a one-sided `area` emitter with the same radiance (a double-sided one to two, back to
     back), the glTF camera to a `perspective` sensor (to_world = camera matrix ×
     diag(−1, 1, −1, 1): Mitsuba's camera looks down +Z with +X to the left), a box pixel
     filter, and the `direct` integrator (one emitter and one BSDF sample, MIS: portalview's
     --max-depth 1). The portal nodes are left out: they are invisible in portalview too;
  2. writes the same scene back as a .glb for portalview with every material made exactly
     Lambertian (`KHR_materials_specular` with `specularFactor` 0, which portalview reads as
     "no specular layer"), so that both renderers see the same materials;
  3. renders it with Mitsuba at 256×256 after a warm-up render (which JIT-compiles the
     kernels), twice at 1024 spp with different seeds: samples/s, and the MSE of one render
     as half the mean squared difference of the two (independent, unbiased renders);
  4. renders it with portalview (light and antishadow sampling, its default Sobol' sampler):
     samples/s, and the samples per pixel, hence the time, at which its MSE (also from pairs of
     renders with different seeds, at 1, 4, 16, ... spp, interpolated) reaches Mitsuba's
     1024-spp MSE. Mitsuba's rate is the faster render of its pair; portalview's is the
     fastest of `--rate-rounds` renders of 64 spp per strategy, the strategies alternated
     (so that a slow spell of the machine does not fall on one strategy only), or with
     `--rate-rounds 0` the faster render of its last pair;
  5. checks that the two renderers' images agree: per 16×16 block, the difference of the
     means over its standard error (from the pairs), and the ratio of the image means.

Run it through `bench/peers/run.sh`, which makes the virtual environment and finds LLVM.
"""

import argparse
import json
import math
import os
import re
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
SIZE = 256

# ---------------------------------------------------------------------------------------------
# glTF reading (by hand: a .glb is a JSON chunk and a binary chunk)
# ---------------------------------------------------------------------------------------------


def read_glb(path):
    data = path.read_bytes()
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2:
        raise SystemExit(f"{path}: not a glTF 2 binary")
    offset, gltf, binary = 12, None, b""
    while offset < length:
        chunk_len, chunk_type = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8 : offset + 8 + chunk_len]
        if chunk_type == 0x4E4F534A:
            gltf = json.loads(chunk)
        elif chunk_type == 0x004E4942:
            binary = chunk
        offset += 8 + chunk_len
    if gltf is None:
        raise SystemExit(f"{path}: no JSON chunk")
    return gltf, binary


COMPONENTS = {5120: "i1", 5121: "u1", 5122: "i2", 5123: "u2", 5125: "u4", 5126: "f4"}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def accessor(gltf, binary, index):
    a = gltf["accessors"][index]
    view = gltf["bufferViews"][a["bufferView"]]
    dtype = np.dtype("<" + COMPONENTS[a["componentType"]])
    n, width = a["count"], WIDTH[a["type"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    stride = view.get("byteStride", 0) or dtype.itemsize * width
    if stride == dtype.itemsize * width:
        out = np.frombuffer(binary, dtype, n * width, start)
        return out.reshape(n, width) if width > 1 else out
    out = np.vstack(
        [np.frombuffer(binary, dtype, width, start + i * stride) for i in range(n)]
    )
    return out.reshape(n, width) if width > 1 else out.reshape(n)


def quat_matrix(q):
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def local_matrix(node):
    if "matrix" in node:
        return np.array(node["matrix"], dtype=float).reshape(4, 4).T
    m = np.eye(4)
    m[:3, :3] = quat_matrix(node.get("rotation", [0, 0, 0, 1])) * np.array(
        node.get("scale", [1, 1, 1])
    )
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def world_nodes(gltf):
    """(node, world matrix) for every node reachable from the default scene."""
    out = []

    def visit(i, parent):
        node = gltf["nodes"][i]
        m = parent @ local_matrix(node)
        out.append((node, m))
        for c in node.get("children", []):
            visit(c, m)

    for i in gltf["scenes"][gltf.get("scene", 0)]["nodes"]:
        visit(i, np.eye(4))
    return out


# ---------------------------------------------------------------------------------------------
# Conversion
# ---------------------------------------------------------------------------------------------


def write_ply(path, positions, faces, normals=None):
    names = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals is not None else [])
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(positions)}\n"
        + "".join(f"property float {n}\n" for n in names)
        + f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    vertices = positions if normals is None else np.c_[positions, normals]
    face_rows = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", 3)])
    face_rows["n"] = 3
    face_rows["i"] = faces
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(np.asarray(vertices, dtype="<f4").tobytes())
        f.write(face_rows.tobytes())


def material_params(gltf, index):
    m = gltf["materials"][index] if index is not None else {}
    pbr = m.get("pbrMetallicRoughness", {})
    base = pbr.get("baseColorFactor", [1, 1, 1, 1])[:3]
    strength = m.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get(
        "emissiveStrength", 1.0
    )
    emission = [c * strength for c in m.get("emissiveFactor", [0, 0, 0])]
    return base, emission, m.get("doubleSided", False)


RUG_TRIANGLES = 1_000_000


def add_rug(gltf, binary):
    """`gltf` with a rug of `RUG_TRIANGLES` triangles (a 500 × 1000 grid of quads, grey,
    facing up) on its lowest surface, over the middle 80% of the scene's extent, its height
    a field of bumps up to 1/500 of that extent (seeded): geometry where rays cost more, as
    in a scanned or sculpted scene. Returns the new JSON and binary chunk."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for node, world in world_nodes(gltf):
        if "mesh" not in node or "portal_target" in node.get("extras", {}):
            continue
        for prim in gltf["meshes"][node["mesh"]]["primitives"]:
            pos = accessor(gltf, binary, prim["attributes"]["POSITION"]).astype(float)
            pos = (np.c_[pos, np.ones(len(pos))] @ world.T)[:, :3]
            lo, hi = np.minimum(lo, pos.min(axis=0)), np.maximum(hi, pos.max(axis=0))
    nx, nz = 500, RUG_TRIANGLES // 1000
    (x0, z0), (x1, z1) = lo[[0, 2]] * 0.8 + hi[[0, 2]] * 0.2, lo[[0, 2]] * 0.2 + hi[[0, 2]] * 0.8
    amplitude = (hi - lo)[[0, 2]].max() / 500.0
    xs, zs = np.meshgrid(np.linspace(x0, x1, nx + 1), np.linspace(z0, z1, nz + 1), indexing="ij")
    rng = np.random.default_rng(0)
    k = 2 * np.pi / (40 * amplitude)
    bumps = 0.5 + 0.25 * (np.sin(k * xs) * np.sin(0.7 * k * zs) + np.sin(0.3 * k * (xs + zs)))
    y = lo[1] + amplitude * (0.05 + 0.9 * np.clip(bumps + 0.05 * rng.standard_normal(xs.shape), 0, 1))
    positions = np.stack([xs, y, zs], axis=-1).reshape(-1, 3).astype("<f4")
    i = np.arange(nx)[:, None] * (nz + 1) + np.arange(nz)[None, :]
    a, b, c, d = i, i + 1, i + nz + 2, i + nz + 1
    # Counter-clockwise seen from above (+y): x right, z toward the viewer.
    faces = np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], -2).reshape(-1, 3)
    indices = faces.astype("<u4")
    binary = binary + b"\0" * (-len(binary) % 4)
    views = gltf.setdefault("bufferViews", [])
    accessors = gltf.setdefault("accessors", [])
    for data, target in ((positions, 34962), (indices, 34963)):
        views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": data.nbytes,
                      "target": target})
        binary += data.tobytes()
    accessors.append({"bufferView": len(views) - 2, "componentType": 5126, "count": len(positions),
                      "type": "VEC3", "min": positions.min(0).tolist(),
                      "max": positions.max(0).tolist()})
    accessors.append({"bufferView": len(views) - 1, "componentType": 5125,
                      "count": indices.size, "type": "SCALAR"})
    gltf["buffers"][0]["byteLength"] = len(binary)
    materials = gltf.setdefault("materials", [])
    materials.append({"name": "rug", "pbrMetallicRoughness": {
        "baseColorFactor": [0.45, 0.4, 0.35, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}})
    gltf.setdefault("meshes", []).append({"name": "rug", "primitives": [{
        "attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1,
        "material": len(materials) - 1}]})
    gltf["nodes"].append({"name": "rug", "mesh": len(gltf["meshes"]) - 1})
    gltf["scenes"][gltf.get("scene", 0)]["nodes"].append(len(gltf["nodes"]) - 1)
    return gltf, binary


def convert(glb, out_dir, mi, rug=False):
    """The Mitsuba scene dict of `glb` (PLYs written to `out_dir`), and the path of the
    Lambertian .glb for portalview; with `rug`, both with [`add_rug`]'s rug."""
    gltf, binary = read_glb(glb)
    if rug:
        gltf, binary = add_rug(gltf, binary)
    if "KHR_lights_punctual" in gltf.get("extensionsUsed", []):
        raise SystemExit(f"{glb}: lamps (KHR_lights_punctual) are not converted")
    scene = {
        "type": "scene",
        "integrator": {"type": "direct"},
    }
    camera = None
    for k, (node, world) in enumerate(world_nodes(gltf)):
        if "camera" in node and camera is None:
            cam = gltf["cameras"][node["camera"]]["perspective"]
            to_world = world @ np.diag([-1.0, 1.0, -1.0, 1.0])
            camera = {
                "type": "perspective",
                "fov_axis": "y",
                "fov": math.degrees(cam["yfov"]),
                "near_clip": cam.get("znear", 0.01),
                "far_clip": 1e4,
                "to_world": mi.ScalarTransform4f(to_world.tolist()),
                "sampler": {"type": "independent", "sample_count": 1},
                "film": {
                    "type": "hdrfilm",
                    "width": SIZE,
                    "height": SIZE,
                    "rfilter": {"type": "box"},
                    "pixel_format": "rgb",
                },
            }
        if "mesh" not in node or "portal_target" in node.get("extras", {}):
            continue
        for p, prim in enumerate(gltf["meshes"][node["mesh"]]["primitives"]):
            if prim.get("mode", 4) != 4:
                raise SystemExit(f"{glb}: mesh {node['mesh']}: only triangle lists")
            pos = accessor(gltf, binary, prim["attributes"]["POSITION"]).astype(float)
            pos = (np.c_[pos, np.ones(len(pos))] @ world.T)[:, :3]
            if "indices" in prim:
                faces = accessor(gltf, binary, prim["indices"]).astype(np.int64).reshape(-1, 3)
            else:
                faces = np.arange(len(pos)).reshape(-1, 3)
            if np.linalg.det(world[:3, :3]) < 0:
                faces = faces[:, ::-1]  # a mirroring transform flips the front face
            # Vertex normals where the file has them (portalview interpolates them for
            # shading, so a smooth object must not be faceted here); face normals elsewhere.
            normals = None
            if "NORMAL" in prim["attributes"]:
                normals = accessor(gltf, binary, prim["attributes"]["NORMAL"]).astype(float)
                normals = normals @ np.linalg.inv(world[:3, :3])
                normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
            name = f"shape{k}_{p}"
            ply = out_dir / f"{name}.ply"
            write_ply(ply, pos, faces, normals)
            base, emission, double_sided = material_params(gltf, prim.get("material"))
            shape = {
                "type": "ply",
                "filename": str(ply),
                "face_normals": normals is None,
                "bsdf": {
                    "type": "twosided",
                    "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": base}},
                },
            }
            if max(emission) > 0:
                shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": emission}}
                if double_sided:
                    # Mitsuba's area lights emit on the front only: add a copy facing the other
                    # way, 0.1 mm behind, which rays from the back meet first.
                    n = np.cross(pos[faces[:, 1]] - pos[faces[:, 0]], pos[faces[:, 2]] - pos[faces[:, 0]])
                    n = n.sum(axis=0) / max(np.linalg.norm(n.sum(axis=0)), 1e-12)
                    back = out_dir / f"{name}_back.ply"
                    write_ply(back, pos - 1e-4 * n, faces[:, ::-1], None if normals is None else -normals)
                    scene[name + "_back"] = dict(shape, filename=str(back))
            scene[name] = shape
    if camera is None:
        raise SystemExit(f"{glb}: no camera")
    scene["sensor"] = camera

    # The same scene for portalview, every material exactly Lambertian: no metal (the
    # lampshade's brass becomes a diffuse of its base colour) and no specular layer.
    for m in gltf.get("materials", []):
        m.setdefault("pbrMetallicRoughness", {})["metallicFactor"] = 0.0
        m.setdefault("extensions", {})["KHR_materials_specular"] = {"specularFactor": 0.0}
    used = gltf.setdefault("extensionsUsed", [])
    if "KHR_materials_specular" not in used:
        used.append("KHR_materials_specular")
    lambert = out_dir / f"{glb.stem}-lambert.glb"
    write_glb(lambert, gltf, binary)
    return scene, lambert


def write_glb(path, gltf, binary):
    text = json.dumps(gltf, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary = binary + b"\0" * (-len(binary) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text
    chunks += struct.pack("<II", len(binary), 0x004E4942) + binary
    path.write_bytes(struct.pack("<4sII", b"glTF", 2, 12 + len(chunks)) + chunks)


# ---------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------


def mitsuba_render(mi, dr, scene, spp, seed):
    start = time.perf_counter()
    img = mi.render(scene, spp=spp, seed=seed)
    dr.eval(img)
    out = np.array(img, dtype=np.float64)
    return out, time.perf_counter() - start


def read_exr(path):
    import mitsuba as mi

    return np.array(mi.Bitmap(str(path)), dtype=np.float64)[..., :3]


SUMMARY = re.compile(r"(\d+) spp in ([0-9.]+) s: ([0-9.]+) M samples/s")


def portalview_render(binary, glb, strategy, sampler, spp, seed, out):
    cmd = [
        str(binary), "render", "--scene", str(glb), "--strategy", strategy,
        "--sampler", sampler, "--spp", str(spp), "--seed", str(seed),
        "--width", str(SIZE), "--height", str(SIZE), "--max-depth", "1", "--out", str(out),
    ]
    res = subprocess.run(cmd, capture_output=True, text=True, check=True)
    m = SUMMARY.search(res.stdout)
    if not m:
        raise SystemExit(f"cannot read portalview's summary: {res.stdout}")
    # The time from the printed rate (three decimals of M samples/s), not the printed seconds
    # (two decimals: a 0.3 s render would be timed to ±2%).
    return read_exr(out), SIZE * SIZE * int(m.group(1)) / (float(m.group(3)) * 1e6)


def pair_mse(a, b):
    """The MSE of one of two independent unbiased renders: E|a − b|² = 2 · MSE."""
    return float(np.mean((a - b) ** 2) / 2.0)


def portalview_time_to(binary, glb, strategy, sampler, target, tmp, max_spp):
    """spp and seconds at which portalview's MSE reaches `target`, and its samples/s.
    Pairs of renders at 1, 4, 16, ... spp (powers of two, so that a Sobol' prefix is a full
    net) until the pair's MSE is at most `target`; the crossing is interpolated in log–log
    between the last two (or extrapolated by 1/spp past `max_spp`). The rate is the faster of
    the last pair's two renders (the machine may be shared)."""
    def pair(spp):
        a, ta = portalview_render(binary, glb, strategy, sampler, spp, 1, tmp / "a.exr")
        b, tb = portalview_render(binary, glb, strategy, sampler, spp, 2, tmp / "b.exr")
        return pair_mse(a, b), SIZE * SIZE * spp / min(ta, tb), (a, b)

    previous, n = None, 1
    while True:
        mse, rate, renders = pair(n)
        if mse <= target or n >= max_spp:
            break
        previous, n = (n, mse), n * 4
    if mse > target:
        spp = n * mse / target
    elif previous is None:
        spp = n
    else:
        n0, mse0 = previous
        slope = math.log(mse0 / mse) / math.log(n / n0) if mse0 > mse else 1.0
        spp = n0 * (mse0 / target) ** (1.0 / max(slope, 1e-3))
    spp = max(spp, 1.0)
    return spp, spp * SIZE * SIZE / rate, rate, renders


RATE_SPP = 64


def alternated_rates(binary, glb, strategies, sampler, rounds, tmp):
    """portalview's samples/s per strategy: the fastest of `rounds` renders of `RATE_SPP` spp,
    the strategies taking turns (in reverse order every other round)."""
    best = {s: 0.0 for s in strategies}
    for r in range(rounds):
        for s in strategies if r % 2 == 0 else strategies[::-1]:
            _, t = portalview_render(binary, glb, s, sampler, RATE_SPP, 3 + r, tmp / "rate.exr")
            best[s] = max(best[s], SIZE * SIZE * RATE_SPP / t)
    return best


def agreement(mit, pv):
    """Per 16×16 block of luminance: z-scores of the difference of the means, from each
    renderer's pair of independent renders; and the ratio of the image means with its
    standard error."""
    lum = lambda x: x.mean(axis=-1)
    (ma, mb), (pa, pb) = [tuple(lum(x) for x in p) for p in (mit, pv)]
    m, p = (ma + mb) / 2, (pa + pb) / 2
    # The variance of a pair's mean, per pixel: (a − b)²/4.
    vm, vp = (ma - mb) ** 2 / 4, (pa - pb) ** 2 / 4
    b = 16
    shape = (SIZE // b, b, SIZE // b, b)
    block = lambda x: x.reshape(shape).mean(axis=(1, 3))
    block_var = lambda v: v.reshape(shape).sum(axis=(1, 3)) / (b * b) ** 2
    d = block(p) - block(m)
    se = np.sqrt(block_var(vm) + block_var(vp))
    lit = se > 0
    z = d[lit] / se[lit]
    ratio = p.mean() / m.mean()
    ratio_se = math.sqrt(vp.sum() / p.size ** 2 + vm.sum() / m.size ** 2 * ratio ** 2) / m.mean()
    return z, ratio, ratio_se


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--portalview", default=str(ROOT / "target/release/portalview"))
    ap.add_argument("--spp", type=int, default=1024, help="Mitsuba's samples per pixel")
    ap.add_argument(
        "--scenes", default="lampshade,fig8a,fig8b,fig8c",
        help="built-in names; NAME+rug adds a rug of a million triangles (add_rug)",
    )
    ap.add_argument("--strategies", default="light,antishadow")
    ap.add_argument("--sampler", default="sobol", help="portalview's sampler")
    ap.add_argument("--max-spp", type=int, default=16384)
    ap.add_argument(
        "--rate-rounds", type=int, default=3,
        help="rounds of alternated 64-spp renders that measure portalview's samples/s "
        "(the fastest counts); 0 takes the faster render of the last pair instead",
    )
    args = ap.parse_args()

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("llvm_ad_rgb")
    binary = Path(args.portalview)
    rows, checks = [], []
    with tempfile.TemporaryDirectory(prefix="portalview-peers-") as tmp:
        tmp = Path(tmp)
        for name in args.scenes.split(","):
            scene_dir = tmp / name
            scene_dir.mkdir()
            # `NAME+rug`: the built-in with a rug of a million triangles (`add_rug`).
            base, rug = name.removesuffix("+rug"), name.endswith("+rug")
            desc, lambert = convert(ROOT / "assets" / f"{base}.glb", scene_dir, mi, rug)
            scene = mi.load_dict(desc)
            mitsuba_render(mi, dr, scene, args.spp, 0)  # warm-up: JIT compilation
            a, ta = mitsuba_render(mi, dr, scene, args.spp, 1)
            b, tb = mitsuba_render(mi, dr, scene, args.spp, 2)
            target = pair_mse(a, b)
            # The faster of the two (the machine may be shared), as for portalview.
            mitsuba_rate = SIZE * SIZE * args.spp / min(ta, tb)
            mitsuba_time = SIZE * SIZE * args.spp / mitsuba_rate
            rows.append((name, "Mitsuba 3 llvm_ad_rgb", mitsuba_rate, args.spp, mitsuba_time, target))
            print(f"{name}: Mitsuba {mitsuba_rate / 1e6:.2f} M samples/s, MSE at {args.spp} spp {target:.3e}", flush=True)
            strategies = args.strategies.split(",")
            found = {}
            for strategy in strategies:
                spp, _, rate, pair = portalview_time_to(
                    binary, lambert, strategy, args.sampler, target, tmp, args.max_spp
                )
                found[strategy] = (spp, rate)
                if strategy == "light":
                    z, ratio, ratio_se = agreement((a, b), pair)
                    checks.append((name, z, ratio, ratio_se))
            if args.rate_rounds > 0:
                rates = alternated_rates(
                    binary, lambert, strategies, args.sampler, args.rate_rounds, tmp
                )
                found = {s: (found[s][0], rates[s]) for s in strategies}
            for strategy in strategies:
                spp, rate = found[strategy]
                seconds = spp * SIZE * SIZE / rate
                rows.append((name, f"portalview {strategy} ({args.sampler})", rate, spp, seconds, target))
                print(f"{name}: portalview {strategy} {rate / 1e6:.2f} M samples/s, {spp:.0f} spp, {seconds:.2f} s to Mitsuba's MSE", flush=True)

    print()
    print(f"| scene | renderer | M samples/s | spp to Mitsuba's {args.spp}-spp MSE | seconds to it | vs Mitsuba |")
    print("|---|---|---:|---:|---:|---:|")
    for name, who, rate, spp, seconds, _ in rows:
        base = next(r[4] for r in rows if r[0] == name)
        print(f"| {name} | {who} | {rate / 1e6:.2f} | {spp:.0f} | {seconds:.2f} | {base / seconds:.2f}x sooner |")
    print()
    print("Image agreement (portalview light sampling against Mitsuba, luminance, 16x16 blocks):")
    print("| scene | blocks | mean z | mean z^2 | max abs z | image mean ratio pv/Mitsuba |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, z, ratio, ratio_se in checks:
        print(f"| {name} | {len(z)} | {z.mean():+.2f} | {np.mean(z ** 2):.2f} | {np.abs(z).max():.1f} | {ratio:.4f} ± {ratio_se:.4f} |")


if __name__ == "__main__":
    main()
