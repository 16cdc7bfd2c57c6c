#!/usr/bin/env python3
"""Render the Cornell box with Mitsuba 3 and with our renderer; compare radiance and speed.

Mitsuba renders `mitsuba.cornell_box()` (path tracer, independent sampler, Gaussian film filter)
with the film size, spp and max_depth set from the command line. Our renderer renders
scenes/cornell-box/scene.gltf (written by make_cornell_box.py from the same scene):

    target/release/render scenes/cornell-box/scene.gltf --spp N --resolution WxH \
        --max-depth D --output OUT.exr --stats OUT.json

whose stats JSON holds at least "wall_seconds" and "samples_per_second" (samples = pixel
samples, width * height * spp).

Field of view: mitsuba.cornell_box() has fov 39.3077 deg on the 'smaller' axis; the glTF keeps
yfov = 39.3077 deg and takes the aspect from the output resolution. Here Mitsuba's sensor is set
to fov_axis 'y' with that yfov so both agree for any resolution (identical to cornell_box() for
square and landscape images).

Timing of Mitsuba: the scene is loaded (not timed as rendering), rendered once at --warmup-spp
("cold": includes Dr.Jit's tracing and kernel compilation, or its load from Dr.Jit's kernel
cache), then rendered at --spp ("warm", the figure used for samples/s). Both are reported, plus
an estimate of the one-off overhead = cold - warm * warmup_spp / spp. Dr.Jit keeps compiled
kernels in ~/.drjit, so "cold" is only a real compilation the first time, or with
--no-kernel-cache (a fresh DRJIT_CACHE_DIR).

    python3 assets-scripts/compare_mitsuba.py --mitsuba-only --spp 64
    python3 assets-scripts/compare_mitsuba.py                     # 512x512, 256 spp, depth 8, llvm_ad_rgb
"""

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from make_cornell_box import SENSOR, find_libllvm, vertical_fov_deg  # noqa: E402


def parse_resolution(s):
    parts = s.lower().split("x")
    if len(parts) == 1:
        return int(parts[0]), int(parts[0])
    if len(parts) == 2:
        return int(parts[0]), int(parts[1])
    raise argparse.ArgumentTypeError(f"resolution must be WxH or N, got {s!r}")


def set_variant(variant):
    """Import mitsuba with `variant`; an LLVM variant falls back to scalar_rgb if LLVM is missing."""
    if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
        p = find_libllvm()
        if p:
            os.environ["DRJIT_LIBLLVM_PATH"] = p
    import mitsuba as mi
    try:
        mi.set_variant(variant)
        mi.load_dict({"type": "sphere"})  # an LLVM variant only fails on first use
    except (ImportError, AttributeError, RuntimeError) as e:
        if variant == "scalar_rgb":
            raise
        print(f"WARNING: Mitsuba variant {variant} unavailable ({str(e).splitlines()[0]}); "
              "falling back to scalar_rgb. For llvm_ad_rgb: apt-get install libllvm19 and set "
              "DRJIT_LIBLLVM_PATH to the libLLVM.so.19* listed by `dpkg -L libllvm19`.", file=sys.stderr)
        mi.set_variant("scalar_rgb")
    return mi


def channel_means(img):
    return img[..., :3].reshape(-1, 3).astype(np.float64).mean(0)


def fmt(v, p=5):
    return "[" + ", ".join(f"{x:.{p}f}" for x in v) + "]"


def render_mitsuba(args, width, height, out_prefix):
    mi = set_variant(args.variant)
    import drjit as dr
    if args.threads:
        dr.set_thread_count(args.threads)
    d = mi.cornell_box()
    s = d["sensor"]
    s["film"]["width"], s["film"]["height"] = width, height
    s["film"]["rfilter"] = {"type": args.rfilter}
    s["fov_axis"] = "y"
    s["fov"] = vertical_fov_deg(SENSOR["fov"], SENSOR["fov_axis"], SENSOR["width"], SENSOR["height"])
    d["integrator"]["max_depth"] = args.max_depth

    t0 = time.perf_counter()
    scene = mi.load_dict(d)
    t_load = time.perf_counter() - t0

    t0 = time.perf_counter()
    np.array(mi.render(scene, spp=args.warmup_spp, seed=args.seed + 1))
    t_cold = time.perf_counter() - t0

    t0 = time.perf_counter()
    img = np.array(mi.render(scene, spp=args.spp, seed=args.seed))
    t_warm = time.perf_counter() - t0

    out_exr = f"{out_prefix}_mitsuba-{mi.variant()}.exr"
    mi.Bitmap(img).write(out_exr)
    n = width * height * args.spp
    return {
        "variant": mi.variant(), "mitsuba_version": mi.__version__, "threads": dr.thread_count(),
        "resolution": [width, height], "spp": args.spp, "max_depth": args.max_depth, "rfilter": args.rfilter,
        "load_seconds": t_load, "warmup_spp": args.warmup_spp, "cold_seconds": t_cold,
        "cold_samples_per_second": width * height * args.warmup_spp / t_cold,
        "wall_seconds": t_warm, "samples_per_second": n / t_warm,
        "jit_overhead_estimate_seconds": t_cold - t_warm * args.warmup_spp / args.spp,
        "mean_rgb": channel_means(img).tolist(), "exr": out_exr,
    }, img


def read_exr(path):
    """Float RGB array (H, W, 3) from an EXR: the OpenEXR package, else Mitsuba's Bitmap."""
    try:
        import OpenEXR
        with OpenEXR.File(path, separate_channels=True) as f:
            ch = {k: v.pixels for k, v in f.channels().items()}
        names = [c for c in ("R", "G", "B") if c in ch]
        if len(names) < 3:  # e.g. layer-prefixed names: take the last component name
            by_suffix = {k.split(".")[-1]: v for k, v in ch.items()}
            names = [c for c in ("R", "G", "B") if c in by_suffix]
            ch = by_suffix
        if len(names) == 3:
            return np.stack([ch[c] for c in names], -1).astype(np.float32)
        if "Y" in ch:
            return np.repeat(ch["Y"][..., None], 3, -1).astype(np.float32)
        raise ValueError(f"{path}: no R, G, B channels (has {sorted(ch)})")
    except ImportError:
        import mitsuba as mi
        if not mi.variant():
            mi.set_variant("scalar_rgb")
        return np.array(mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False))


def run_render(cmd, out_exr, out_json):
    """Runs our `render` command line `cmd` (which must write `out_exr` and, with --stats,
    `out_json`) from the repository root; returns (its stats, the image, process seconds)."""
    print("running:", " ".join(cmd), flush=True)
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT)
    t_proc = time.perf_counter() - t0
    with open(out_json) as f:
        stats = json.load(f)
    return stats, read_exr(out_exr), t_proc


def render_ours(args, width, height, out_exr, out_json):
    cmd = [args.render_bin, args.scene, "--spp", str(args.spp), "--resolution", f"{width}x{height}",
           "--max-depth", str(args.max_depth), "--output", out_exr, "--stats", out_json] + args.render_arg
    stats, img, t_proc = run_render(cmd, out_exr, out_json)
    n = width * height * args.spp
    wall = float(stats.get("wall_seconds", t_proc))
    return {
        "resolution": [width, height], "spp": args.spp, "max_depth": args.max_depth,
        "wall_seconds": wall, "process_seconds": t_proc,
        "samples_per_second": float(stats.get("samples_per_second", n / wall)),
        "mean_rgb": channel_means(img).tolist(), "exr": out_exr, "stats": stats,
    }, img


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--variant", default="llvm_ad_rgb", help="Mitsuba variant (default llvm_ad_rgb)")
    ap.add_argument("--resolution", type=parse_resolution, default=(512, 512), help="WxH (default 512x512)")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--warmup-spp", type=int, default=1, help="spp of Mitsuba's untimed-for-speed first render")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=0, help="Mitsuba threads (default: all cores)")
    ap.add_argument("--rfilter", default="gaussian", help="Mitsuba film filter (cornell_box(): gaussian; or box)")
    ap.add_argument("--scene", default=os.path.join(ROOT, "scenes", "cornell-box", "scene.gltf"))
    ap.add_argument("--render-bin", default=os.path.join(ROOT, "target", "release", "render"))
    ap.add_argument("--render-arg", action="append", default=[], help="extra argument for our renderer")
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "target", "compare-mitsuba"))
    ap.add_argument("--mitsuba-only", action="store_true", help="skip our renderer")
    ap.add_argument("--no-kernel-cache", action="store_true",
                    help="point DRJIT_CACHE_DIR at a fresh temporary folder so the cold render compiles its kernels")
    args = ap.parse_args()
    if args.no_kernel_cache:
        import atexit
        import shutil
        import tempfile
        os.environ["DRJIT_CACHE_DIR"] = tempfile.mkdtemp(prefix="drjit-cache-")
        atexit.register(shutil.rmtree, os.environ["DRJIT_CACHE_DIR"], True)

    width, height = args.resolution
    os.makedirs(args.out_dir, exist_ok=True)
    tag = f"cornell-box_{width}x{height}_{args.spp}spp_d{args.max_depth}"

    mit, mimg = render_mitsuba(args, width, height, os.path.join(args.out_dir, tag))
    print(f"Mitsuba {mit['mitsuba_version']} {mit['variant']} ({mit['threads']} threads), {width}x{height}, "
          f"{args.spp} spp, max_depth {args.max_depth}, rfilter {args.rfilter}")
    print(f"  load {mit['load_seconds']:.3f} s; cold render ({args.warmup_spp} spp) {mit['cold_seconds']:.3f} s "
          f"= {mit['cold_samples_per_second'] / 1e6:.3f} M samples/s; warm render {mit['wall_seconds']:.3f} s "
          f"= {mit['samples_per_second'] / 1e6:.3f} M samples/s; one-off overhead ~"
          f"{mit['jit_overhead_estimate_seconds']:.3f} s")
    print(f"  mean RGB {fmt(mit['mean_rgb'])}  -> {mit['exr']}")
    summary = {"mitsuba": mit}

    if not args.mitsuba_only:
        ours, oimg = render_ours(args, width, height, os.path.join(args.out_dir, f"{tag}_render.exr"),
                                 os.path.join(args.out_dir, f"{tag}_render.json"))
        ma, mo = np.array(mit["mean_rgb"]), np.array(ours["mean_rgb"])
        rel = (mo - ma) / ma
        ratio = ours["samples_per_second"] / mit["samples_per_second"]
        print(f"render {width}x{height}, {args.spp} spp, max_depth {args.max_depth}: {ours['wall_seconds']:.3f} s "
              f"= {ours['samples_per_second'] / 1e6:.3f} M samples/s")
        print(f"  mean RGB {fmt(mo)}  -> {ours['exr']}")
        print(f"relative difference (render - mitsuba) / mitsuba per channel: {fmt(rel, 4)}")
        print(f"samples/s ratio render / mitsuba: {ratio:.3f}")
        summary.update(render=ours, relative_mean_difference=rel.tolist(), speed_ratio=ratio)
        if oimg.shape[:2] == mimg.shape[:2]:
            # 8x8-block means suppress noise; relative RMSE of those against Mitsuba's
            def blocks(x):
                h, w = (x.shape[0] // 8) * 8, (x.shape[1] // 8) * 8
                return x[:h, :w, :3].reshape(h // 8, 8, w // 8, 8, 3).mean((1, 3))
            bm, bo = blocks(mimg.astype(np.float64)), blocks(oimg.astype(np.float64))
            rrmse = float(np.sqrt(np.mean((bo - bm) ** 2)) / np.mean(bm))
            print(f"relative RMSE of 8x8-block means: {rrmse:.4f}")
            summary["block_relative_rmse"] = rrmse

    out_json = os.path.join(args.out_dir, f"{tag}_summary.json")
    with open(out_json, "w") as f:
        json.dump(summary, f, indent=1)
    print(f"summary -> {out_json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
