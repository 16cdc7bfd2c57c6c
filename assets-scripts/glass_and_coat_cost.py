#!/usr/bin/env python3
"""Speed of glass and of a clear coat on the material preview: the commands to time, and a timer.

Writes into --out-dir (default target/glass-and-coat-cost) copies of
scenes/material-preview/scene.gltf (buffer and environment by relative path) whose sphere is
  glass-smooth   clear solid glass, IOR 1.5 (compare_preview_mitsuba.py --preset glass);
  glass-rough    the same at roughness --roughness (GGX, alpha = roughness^2);
  neural         the shipped code --code alone (extras {"neural": CODE});
  neural-coated  the same under KHR_materials_clearcoat (factor 1, roughness --coat-roughness),
and prints the pairs of whole-process commands that are compared, each as one line:
  glass-smooth: render on glass-smooth against Mitsuba 3 llvm `dielectric` on the same scene
      (compare_preview_mitsuba.py --preset glass --mitsuba-only: the same meshes, camera,
      lights and environment built from make_material_preview.py);
  glass-rough:  render against Mitsuba's `roughdielectric` (GGX) likewise;
  coat:         render on neural-coated against render on neural.
All at the same --resolution, --spp, --max-depth 8 and seed. With --runs N the script also
times them: every command N times, the pairs interleaved (A B A B ...), the whole process
from start to exit (start-up, scene loading, Mitsuba's Python and JIT included), and prints
min / median / max seconds and the median of the per-pair ratios A / B.

Usage: python3 assets-scripts/glass_and_coat_cost.py [--runs 3] [--resolution 256] [--spp 256]
       [--coat-spp 64] [--roughness 0.3] [--code alum-bronze] [--coat-roughness 0.1]
Needs numpy, Mitsuba 3 (llvm_ad_rgb, libLLVM as in README) and a release build of render.
"""

import argparse
import os
import shlex
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import make_material_preview as preview  # noqa: E402
from compare_preview_mitsuba import glass_material, staged_gltf  # noqa: E402

LATENT = os.path.join(ROOT, "scenes", "materials", "latent.bin")
RENDER = os.path.join(ROOT, "target", "release", "render")
COMPARE = os.path.join(HERE, "compare_preview_mitsuba.py")


def scenes(out_dir, args):
    """The staged glTF files, by name."""
    source = os.path.join(preview.DEFAULT_SCENE_DIR, "scene.gltf")
    coat = {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": args.coat_roughness}}
    return {
        "glass-smooth": staged_gltf(source, out_dir, glass_material(0.0, 1.5, False), name="glass-smooth"),
        "glass-rough": staged_gltf(source, out_dir, glass_material(args.roughness, 1.5, False), name="glass-rough"),
        "neural": staged_gltf(source, out_dir, {"extras": {"neural": args.code}}, name="neural"),
        "neural-coated": staged_gltf(source, out_dir, {"extras": {"neural": args.code}, "extensions": coat}, name="neural-coated"),
    }


def commands(out_dir, args):
    """(label, command A, command B) of each comparison: A ours, B the yardstick."""
    paths = scenes(out_dir, args)
    size = f"{args.resolution}x{args.resolution}"

    def render(name, spp, *extra):
        return [RENDER, paths[name], "--spp", str(spp), "--resolution", size, "--max-depth", "8", "--seed", "0",
                "--output", os.path.join(out_dir, f"{name}.exr"), *extra]

    def mitsuba(*preset):
        return [sys.executable, COMPARE, *preset, "--mitsuba-only", "--resolution", str(args.resolution),
                "--spp", str(args.spp), "--max-depth", "8", "--seed", "0", "--out-dir", out_dir]

    neural = ("--material", LATENT)
    return [
        ("glass-smooth", render("glass-smooth", args.spp), mitsuba("--preset", "glass")),
        ("glass-rough", render("glass-rough", args.spp), mitsuba("--preset", "glass", "--roughness", str(args.roughness))),
        ("coat", render("neural-coated", args.coat_spp, *neural), render("neural", args.coat_spp, *neural)),
    ]


def timed(command):
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=0, help="time every command this many times (0: print only)")
    parser.add_argument("--resolution", type=int, default=256)
    parser.add_argument("--spp", type=int, default=256, help="of the glass comparisons")
    parser.add_argument("--coat-spp", type=int, default=64, help="of the coat comparison")
    parser.add_argument("--roughness", type=float, default=0.3, help="of the rough glass")
    parser.add_argument("--code", default="alum-bronze", help="the neural sphere's latent code")
    parser.add_argument("--coat-roughness", type=float, default=0.1)
    parser.add_argument("--out-dir", default=os.path.join(ROOT, "target", "glass-and-coat-cost"))
    args = parser.parse_args()
    out_dir = os.path.abspath(args.out_dir)
    os.makedirs(out_dir, exist_ok=True)
    for label, a, b in commands(out_dir, args):
        print(f"{label}:\n  A {shlex.join(a)}\n  B {shlex.join(b)}")
        if args.runs <= 0:
            continue
        timed(a), timed(b)  # warm-up: caches, Mitsuba's kernel cache
        times = [(timed(a), timed(b)) for _ in range(args.runs)]
        ta, tb = [t[0] for t in times], [t[1] for t in times]
        ratio = statistics.median(x / y for x, y in times)
        print(f"  A {min(ta):.2f} / {statistics.median(ta):.2f} / {max(ta):.2f} s, "
              f"B {min(tb):.2f} / {statistics.median(tb):.2f} / {max(tb):.2f} s, A / B median {ratio:.3f}")


if __name__ == "__main__":
    sys.exit(main())
