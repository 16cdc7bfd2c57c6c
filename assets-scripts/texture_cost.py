#!/usr/bin/env python3
"""What textures cost: the feature showcase rendered as shipped and with every texture
removed (base colour, metallic-roughness, normal, occlusion, emissive and the extensions'
textures; factors, alpha modes, lights and geometry kept), its samples/s over --runs
interleaved rounds (min / median / max) and, per round, textured over untextured.

    python3 assets-scripts/texture_cost.py                  # 512x512, 64 spp, 3 rounds
    python3 assets-scripts/texture_cost.py --spp 16 --runs 5 --threads 1

The untextured copy is written to data/showcase-untextured/scene.gltf (its buffer is the
shipped scene's, referred to by path); images and stats go to data/showcase-untextured/runs/.
Each render is its own process: `target/release/render SCENE --spp N --seed ROUND --threads T
--output OUT.exr --stats OUT.json`, timed by the renderer's own wall_seconds (loading left
out: its samples_per_second). The issue's target is textured / untextured >= 0.8.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

from scale_benchmark import machine_info

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHOWCASE = os.path.join(REPO, "scenes", "feature-showcase", "scene.gltf")
OUT = os.path.join(REPO, "data", "showcase-untextured")


def strip_textures(node):
    """Removes, recursively, every texture reference (an object with an `index` under a key
    ending in `Texture`) from a glTF material; returns how many it removed."""
    removed = 0
    if isinstance(node, dict):
        for key in [k for k, v in node.items() if k.endswith("Texture") and isinstance(v, dict) and "index" in v]:
            del node[key]
            removed += 1
        for value in node.values():
            removed += strip_textures(value)
    elif isinstance(node, list):
        for value in node:
            removed += strip_textures(value)
    return removed


def untextured_scene():
    """Writes the showcase without textures; returns its path and how many references went."""
    with open(SHOWCASE) as f:
        gltf = json.load(f)
    removed = strip_textures(gltf["materials"])
    for key in ("textures", "images", "samplers"):
        gltf.pop(key, None)
    for buffer in gltf["buffers"]:
        buffer["uri"] = os.path.relpath(os.path.join(os.path.dirname(SHOWCASE), buffer["uri"]), OUT)
    os.makedirs(OUT, exist_ok=True)
    path = os.path.join(OUT, "scene.gltf")
    with open(path, "w") as f:
        json.dump(gltf, f, indent=1)
    return path, removed


def render(args, scene, label, run):
    stem = os.path.join(OUT, "runs", f"{label}_{args.spp}spp_run{run}")
    os.makedirs(os.path.dirname(stem), exist_ok=True)
    cmd = [args.render_bin, scene, "--spp", str(args.spp), "--seed", str(run), "--threads", str(args.threads),
           "--output", stem + ".exr", "--stats", stem + ".json"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"texture_cost.py: {' '.join(cmd)} failed: {done.stderr.strip()}")
    with open(stem + ".json") as f:
        stats = json.load(f)
    return stats["samples_per_second"]


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--threads", type=int, default=0, help="render's --threads (0: one per core)")
    parser.add_argument("--render-bin", default=os.path.join(REPO, "target", "release", "render"))
    args = parser.parse_args()
    if not os.path.exists(args.render_bin):
        sys.exit(f"texture_cost.py: {args.render_bin} is missing: cargo build --release -p render-cli")
    plain, removed = untextured_scene()
    scenes = {"textured": SHOWCASE, "untextured": plain}
    rates = {label: [] for label in scenes}
    for run in range(args.runs):
        for label, scene in scenes.items():
            rates[label].append(render(args, scene, label, run))
        print(f"round {run + 1}: " + ", ".join(f"{k} {v[-1] / 1e6:.3f} M samples/s" for k, v in rates.items()), flush=True)
    ratios = [t / u for t, u in zip(rates["textured"], rates["untextured"])]
    spread = lambda v, scale: " / ".join(f"{x * scale:.3f}" for x in (min(v), statistics.median(v), max(v)))
    print(f"\n{machine_info()}; {args.spp} spp, threads {args.threads or os.cpu_count()}, {args.runs} rounds; "
          f"{removed} texture references removed")
    print("| scene | samples/s (M), min / median / max |\n|---|---|")
    for label, v in rates.items():
        print(f"| {label} | {spread(v, 1e-6)} |")
    print(f"| textured / untextured, per round | {spread(ratios, 1.0)} |")


if __name__ == "__main__":
    main()
