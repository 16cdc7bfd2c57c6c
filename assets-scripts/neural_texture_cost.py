#!/usr/bin/env python3
"""What spatially varying neural materials cost against one code, on the material preview.

Writes variants of scenes/material-preview/scene.gltf whose sphere is
  one       the code A alone (extras {"neural": A});
  mix-even  {"mix": [A, B]} with weights (0.5, 0.5) everywhere: both networks at every point;
  mix-half  {"mix": [A, B]} with A on the sphere's left half and B on its right (one network
            per point: a zero weight drops its code);
  blend-mid {"blend": [A, B]} at t = 0.5 everywhere (between palette entries 15 and 16: two
            networks per point);
  blend-ramp{"blend": [A, B]} with t = u across the sphere;
  tint      {"code": A, "tint": stripes};
renders each RUNS times, interleaved, at the same resolution, spp and seed, and prints
min / median / max samples/s per variant, the ratio of medians one / variant (the slowdown),
and load seconds and BSDF memory from --stats.

Usage: python3 assets-scripts/neural_texture_cost.py [--a CODE] [--b CODE] [--runs 3]
       [--spp 64] [--resolution 256x256]
Needs numpy and Pillow; builds render first.
"""

import argparse
import copy
import json
import os
import statistics
import subprocess
import sys
import tempfile

import numpy as np
from PIL import Image

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
PREVIEW = os.path.join(ROOT, "scenes", "material-preview")
LATENT = os.path.join(ROOT, "scenes", "materials", "latent.bin")
RENDER = os.path.join(ROOT, "target", "release", "render")


def variants(a, b):
    """(name, neural extras, texture image or None)."""
    even = np.full((1, 1, 3), [128, 128, 0], np.uint8)
    half = np.array([[[255, 0, 0], [0, 255, 0]]], np.uint8)
    mid = np.full((1, 1, 3), [128, 0, 0], np.uint8)  # 128/255: between entries 15 and 16
    ramp = np.zeros((1, 256, 3), np.uint8)
    ramp[0, :, 0] = np.arange(256)
    stripes = np.zeros((64, 64, 3), np.uint8)
    stripes[(np.arange(64) // 8) % 2 == 0] = [230, 80, 60]
    stripes[(np.arange(64) // 8) % 2 == 1] = [60, 110, 210]
    texture = {"index": 0}
    return [
        ("one", a, None),
        ("mix-even", {"mix": [a, b], "weights": texture}, even),
        ("mix-half", {"mix": [a, b], "weights": texture}, half),
        ("blend-mid", {"blend": [a, b], "t": texture}, mid),
        ("blend-ramp", {"blend": [a, b], "t": texture}, ramp),
        ("tint", {"code": a, "tint": texture}, stripes),
    ]


def write_variants(out_dir, a, b):
    with open(os.path.join(PREVIEW, "scene.gltf")) as f:
        base = json.load(f)
    for name in ["scene.bin", "studio.exr"]:
        os.symlink(os.path.join(PREVIEW, name), os.path.join(out_dir, name))
    paths = {}
    for name, neural, image in variants(a, b):
        doc = copy.deepcopy(base)
        material = next(m for m in doc["materials"] if m["name"] == "preview")
        material["extras"] = {"neural": neural}
        if image is not None:
            Image.fromarray(image, "RGB").save(os.path.join(out_dir, f"{name}.png"))
            doc["images"] = [{"uri": f"{name}.png"}]
            # Nearest, so that a texel's weights are exactly what it says.
            doc["samplers"] = [{"magFilter": 9728, "wrapS": 33071, "wrapT": 33071}]
            doc["textures"] = [{"source": 0, "sampler": 0}]
        paths[name] = os.path.join(out_dir, f"{name}.gltf")
        with open(paths[name], "w") as f:
            json.dump(doc, f)
    return paths


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--a", default="alum-bronze")
    parser.add_argument("--b", default="blue-fabric")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--resolution", default="256x256")
    args = parser.parse_args()
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "render-cli", "--bin", "render"], cwd=ROOT, check=True)
    with tempfile.TemporaryDirectory() as out:
        paths = write_variants(out, args.a, args.b)
        speed = {name: [] for name in paths}
        stats = {}
        for _ in range(args.runs):
            for name, path in paths.items():
                json_path = os.path.join(out, f"{name}.json")
                subprocess.run(
                    [RENDER, path, "--material", LATENT, "--spp", str(args.spp), "--resolution", args.resolution,
                     "--output", os.path.join(out, f"{name}.exr"), "--stats", json_path],
                    check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                )
                with open(json_path) as f:
                    stats[name] = json.load(f)
                speed[name].append(stats[name]["samples_per_second"] / 1e6)
        one = statistics.median(speed["one"])
        print(f"{args.a} / {args.b}, {args.resolution}, {args.spp} spp, {args.runs} interleaved runs (M samples/s)")
        print(f"{'variant':<11} {'min':>6} {'median':>6} {'max':>6} {'cost':>6} {'load s':>7} {'BSDF MB':>8} codes")
        for name, values in speed.items():
            m = stats[name].get("materials", {})
            print(
                f"{name:<11} {min(values):6.3f} {statistics.median(values):6.3f} {max(values):6.3f} "
                f"{one / statistics.median(values):5.2f}x {stats[name]['load_seconds']:7.2f} "
                f"{m.get('bytes', 0) / 1e6:8.1f} {m.get('decoded_codes', '?')}"
            )


if __name__ == "__main__":
    sys.exit(main())
