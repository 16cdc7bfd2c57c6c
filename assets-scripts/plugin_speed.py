#!/usr/bin/env python3
"""Speed of the Mitsuba 3 plugin "neural_brdf" on the material-preview scene, in one run.

Three renders of the same scene (make_material_preview.mitsuba_scene / scene.gltf, same
resolution, spp and max depth), interleaved --runs times, each in its own process:

- mitsuba-neural:  Mitsuba 3 (--variant, default llvm_ad_rgb) with the sphere bound to
                   {"type": "neural_brdf", "filename": LATENT, "material": CODE};
- mitsuba-builtin: the same with Mitsuba's own `roughconductor` (GGX, alpha 0.3, copper);
- render-neural:   our `render` with the sphere bound to the same code.

Mitsuba's time is that of a second render in the same process (the first, at --warmup-spp,
traces and compiles the kernels, which Dr.Jit then reuses); ours is the `render` command's own
rendering time (--stats wall_seconds, after loading). Prints samples/s per run, min/median/max per configuration, and the
ratios of the medians: neural_brdf / roughconductor and neural_brdf / render.

    python3 assets-scripts/plugin_speed.py --code alum-bronze --spp 64 --runs 3
Needs: mitsuba, numpy, the neural_brdf package (pip install ./plugins/python) and
target/release/render.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
from compare_mitsuba import parse_resolution, run_render  # noqa: E402


def mitsuba_child(args):
    """Runs in a child process: one warm-up and one timed Mitsuba render; prints JSON."""
    import time

    import make_material_preview as preview
    from compare_mitsuba import set_variant

    mi = set_variant(args.variant)
    import drjit as dr

    if args.bsdf["type"] == "neural_brdf":
        import neural_brdf.mitsuba

        neural_brdf.mitsuba.register()
    width, height = args.resolution
    scene = mi.load_dict(preview.mitsuba_scene(args.bsdf, width=width, height=height, max_depth=args.max_depth))
    t0 = time.perf_counter()
    dr.eval(mi.render(scene, spp=args.warmup_spp, seed=1))
    dr.sync_thread()
    warmup = time.perf_counter() - t0
    t0 = time.perf_counter()
    image = mi.render(scene, spp=args.spp, seed=0)
    dr.eval(image)
    dr.sync_thread()
    seconds = time.perf_counter() - t0
    print(json.dumps({"seconds": seconds, "warmup_seconds": warmup, "threads": dr.thread_count()}))


def run_mitsuba(args, bsdf):
    command = [
        sys.executable, os.path.abspath(__file__), "--child", json.dumps(bsdf),
        "--variant", args.variant, "--resolution", f"{args.resolution[0]}x{args.resolution[1]}",
        "--spp", str(args.spp), "--warmup-spp", str(args.warmup_spp), "--max-depth", str(args.max_depth),
    ]
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])["seconds"]


def run_ours(args, out_dir):
    stats, exr = os.path.join(out_dir, "stats.json"), os.path.join(out_dir, "render.exr")
    command = [
        args.render_bin, os.path.join(ROOT, "scenes/material-preview/scene.gltf"),
        "--material", args.latent, "--bind", f"preview=neural:{args.code}",
        "--spp", str(args.spp), "--resolution", f"{args.resolution[0]}x{args.resolution[1]}",
        "--max-depth", str(args.max_depth), "--output", exr, "--stats", stats,
    ]
    return run_render(command, exr, stats)[0]["wall_seconds"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", type=json.loads, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--resolution", type=parse_resolution, default=(128, 128), help="WxH or N")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--warmup-spp", type=int, default=4)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--latent", default=os.path.join(ROOT, "scenes/materials/latent.bin"))
    ap.add_argument("--code", default="alum-bronze")
    ap.add_argument("--render-bin", default=os.path.join(ROOT, "target/release/render"))
    args = ap.parse_args()
    if args.child is not None:
        args.bsdf = args.child
        mitsuba_child(args)
        return

    configs = {
        "mitsuba-neural": lambda d: run_mitsuba(args, {"type": "neural_brdf", "filename": args.latent, "material": args.code}),
        "mitsuba-builtin": lambda d: run_mitsuba(args, {"type": "roughconductor", "distribution": "ggx", "alpha": 0.3, "material": "Cu"}),
        "render-neural": lambda d: run_ours(args, d),
    }
    samples = args.resolution[0] * args.resolution[1] * args.spp
    times = {name: [] for name in configs}
    with tempfile.TemporaryDirectory() as out_dir:
        for run in range(args.runs):
            for name, measure in configs.items():
                seconds = measure(out_dir)
                times[name].append(seconds)
                print(f"run {run + 1} {name:16s} {seconds:7.3f} s  {samples / seconds / 1e6:6.3f} M samples/s", flush=True)
    print(f"\n{args.resolution[0]}x{args.resolution[1]}, {args.spp} spp, max depth {args.max_depth}, code {args.code}, {os.cpu_count()} CPUs")
    for name, ts in times.items():
        rates = sorted(samples / t / 1e6 for t in ts)
        print(f"{name:16s} M samples/s min/median/max {rates[0]:.3f} / {statistics.median(rates):.3f} / {rates[-1]:.3f}")
    med = {name: statistics.median(ts) for name, ts in times.items()}
    print(f"time ratio neural_brdf / roughconductor (Mitsuba {args.variant}): {med['mitsuba-neural'] / med['mitsuba-builtin']:.2f}")
    print(f"time ratio Mitsuba neural_brdf / render (same code): {med['mitsuba-neural'] / med['render-neural']:.2f}")


if __name__ == "__main__":
    main()
