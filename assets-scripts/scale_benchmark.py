#!/usr/bin/env python3
"""Scale benchmark: the ≥ 10 M-triangle-instance scene of make_scale_scene.py rendered by our
renderer with instancing, by our renderer with every instance copied into world space
(`render --flatten-instances`) and by Mitsuba 3 (llvm_ad_rgb and scalar_rgb by default, the
same geometry as PLY shapegroups + instances), each run as its own process; prints and writes a
markdown table of min / median / max over the runs.

Generates data/scale-scene/ first if scene.gltf is missing. Then --runs interleaved rounds of
(a) ours instanced, (b) ours --flatten-instances, (c) Mitsuba, once per --variant, with seed =
the round's index (so the means over the rounds average independent images). Each child runs
under GNU time (`/usr/bin/time -f %M`, Debian package `time`) for its peak resident set size.
Ours:

    target/release/render data/scale-scene/scene.gltf --spp N --resolution WxH --max-depth 8 \
        --seed R --output OUT.exr --stats OUT.json [--flatten-instances]

Mitsuba: this script's --mitsuba-child mode, which loads and renders in its own process and
writes the same kind of JSON. Quantities:
- parse: ours `parse_seconds` (reading the glTF and its buffer, world-space triangles of the
  meshes used once; with --flatten-instances also copying the 500 instances into world space);
  Mitsuba: loading the 51 PLY files as shapes (`mi.load_dict` of each `ply`).
- prepare: ours `prepare_seconds` (BVHs, materials, lights); Mitsuba: `mi.load_dict` of the
  scene given the loaded shapes (shapegroups, instances, emitters, sensor, and the Embree BVH
  build, which Mitsuba's CPU variants do synchronously inside load_dict).
- load = parse + prepare.
- render: ours `wall_seconds`; Mitsuba: the third `mi.render` call of the process, at --spp,
  after two at 1 spp: the first ("first render") includes Dr.Jit's LLVM compilation of the
  kernel, the second ("second render") what every further call costs besides the samples.
  With llvm_ad_rgb that is large in this scene: each call re-records the virtual calls of all
  551 shapes (each instance is its own callee): about 11 s a call here with the 500 instances,
  growing with their number (0.4 s with none, 4 s with 100); "samples/s beyond the second
  render" = width·height·(spp − 1) / (render − second render) estimates its throughput
  without it. scalar_rgb (Embree, one path at a time) has no such cost.
- samples/s = width x height x spp / render seconds.
- whole process: wall time of the child (start, load, render, writing the image, exit).
- peak RSS: the child's maximum resident set size (GNU time); for Mitsuba also its peak at the
  end of loading (VmHWM read by the child), which leaves out the JIT compiler and rendering.
- mean radiance per channel of each image; the report gives the relative differences of the
  means over all rounds against ours instanced and flags those beyond --tolerance (2 %).

    python3 assets-scripts/scale_benchmark.py                  # 640x360, 64 spp, 3 runs
    python3 assets-scripts/scale_benchmark.py --resolution 320x180 --spp 8 --runs 1 --variant scalar_rgb

Outputs: images and stats in data/scale-scene/benchmark/, all records in its records.json, the
report (machine: lscpu model name, cores, memory, load average; versions; the table) in
--output (default data/scale-scene/benchmark.md). Exit status 1 when a mean differs by more
than --tolerance.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import make_scale_scene  # noqa: E402
from compare_mitsuba import (  # noqa: E402
    ROOT, channel_means, fmt, parse_resolution, read_exr, run_render, set_variant)

DEFAULT_RESOLUTION = (640, 360)
DEFAULT_SPP = 64
DEFAULT_RUNS = 3
DEFAULT_MAX_DEPTH = 8
DEFAULT_VARIANTS = ["llvm_ad_rgb", "scalar_rgb"]
DEFAULT_TOLERANCE = 0.02
WARMUP_SPP = 1
GNU_TIME = "/usr/bin/time"
OURS = ["instanced", "flattened"]
# (record key, row label, format, scale)
QUANTITIES = [
    ("parse_seconds", "parse (s)", "{:.2f}", 1.0),
    ("prepare_seconds", "prepare: BVH build etc. (s)", "{:.2f}", 1.0),
    ("load_seconds", "load = parse + prepare (s)", "{:.2f}", 1.0),
    ("render_seconds", "render (s)", "{:.2f}", 1.0),
    ("samples_per_second", "samples/s (M)", "{:.3f}", 1e-6),
    ("process_seconds", "whole process (s)", "{:.2f}", 1.0),
    ("peak_rss_mib", "peak RSS (MiB)", "{:.0f}", 1.0),
    ("load_rss_mib", "peak RSS after loading (MiB)", "{:.0f}", 1.0),
    ("first_render_seconds", f"Mitsuba: first render, {WARMUP_SPP} spp (s)", "{:.2f}", 1.0),
    ("repeat_render_seconds", f"Mitsuba: second render, {WARMUP_SPP} spp (s)", "{:.2f}", 1.0),
    ("marginal_samples_per_second", "Mitsuba: samples/s beyond the second render (M)", "{:.3f}", 1e-6),
]


def timed(cmd, rss_path):
    """`cmd` under GNU time, which writes the child's peak RSS (KiB) to rss_path."""
    return [GNU_TIME, "-f", "%M", "-o", rss_path] + cmd


def read_rss_mib(path):
    with open(path) as f:
        return int(f.read().split()[-1]) / 1024.0


def vm_hwm_mib():
    """This process's peak resident set size so far (Linux /proc/self/status VmHWM), MiB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def paths(args, config, run):
    stem = os.path.join(args.out_dir, f"{config}_{args.resolution[0]}x{args.resolution[1]}_{args.spp}spp_run{run}")
    return stem + ".exr", stem + ".json", stem + ".rss"


def run_ours(args, flatten, run):
    exr, stats_json, rss = paths(args, "flattened" if flatten else "instanced", run)
    width, height = args.resolution
    cmd = [args.render_bin, args.scene, "--spp", str(args.spp), "--resolution", f"{width}x{height}",
           "--max-depth", str(args.max_depth), "--seed", str(run), "--output", exr, "--stats", stats_json]
    stats, img, t_proc = run_render(timed(cmd + ["--flatten-instances"] * flatten, rss), exr, stats_json)
    return {
        "parse_seconds": stats["parse_seconds"], "prepare_seconds": stats["prepare_seconds"],
        "load_seconds": stats["load_seconds"], "render_seconds": stats["wall_seconds"],
        "samples_per_second": width * height * args.spp / stats["wall_seconds"],
        "process_seconds": t_proc, "peak_rss_mib": read_rss_mib(rss),
        "mean_rgb": channel_means(img).tolist(), "stored_triangles": stats["stored_triangles"],
        "triangle_instances": stats["triangle_instances"], "instances": stats["instances"],
        "threads": stats["threads"], "traversal": [stats["closest_traversal"], stats["occlusion_traversal"]],
    }


def run_mitsuba(args, variant, run):
    exr, stats_json, rss = paths(args, f"mitsuba-{variant}", run)
    cmd = [sys.executable, os.path.abspath(__file__), "--mitsuba-child", stats_json, "--child-exr", exr,
           "--child-seed", str(run), "--resolution", "{}x{}".format(*args.resolution), "--spp", str(args.spp),
           "--max-depth", str(args.max_depth), "--variant", variant, "--scene-dir", args.scene_dir]
    stats, img, t_proc = run_render(timed(cmd, rss), exr, stats_json)
    return dict(stats, process_seconds=t_proc, peak_rss_mib=read_rss_mib(rss), mean_rgb=channel_means(img).tolist())


def mitsuba_child(args):
    """--mitsuba-child mode: load and render with Mitsuba in this process; write EXR and JSON."""
    mi = set_variant(args.variant[-1])
    import drjit as dr

    width, height = args.resolution
    t0 = time.perf_counter()
    shapes = {name: mi.load_dict(d) for name, d in make_scale_scene.mitsuba_mesh_dicts(args.scene_dir).items()}
    dr.sync_thread()
    t_parse = time.perf_counter() - t0
    t0 = time.perf_counter()
    scene = mi.load_dict(make_scale_scene.mitsuba_scene(args.scene_dir, width, height, args.spp,
                                                        args.max_depth, shapes=shapes))
    dr.sync_thread()
    t_prepare = time.perf_counter() - t0
    load_rss = vm_hwm_mib()
    t0 = time.perf_counter()
    np.array(mi.render(scene, spp=WARMUP_SPP, seed=args.child_seed + 1000))
    t_first = time.perf_counter() - t0
    t0 = time.perf_counter()
    np.array(mi.render(scene, spp=WARMUP_SPP, seed=args.child_seed + 2000))
    t_repeat = time.perf_counter() - t0
    t0 = time.perf_counter()
    img = np.array(mi.render(scene, spp=args.spp, seed=args.child_seed))
    t_render = time.perf_counter() - t0
    marginal = width * height * (args.spp - WARMUP_SPP) / (t_render - t_repeat) if t_render > t_repeat else None
    mi.Bitmap(img).write(args.child_exr)
    record = {
        "variant": mi.variant(), "mitsuba_version": mi.__version__, "threads": dr.thread_count(),
        "parse_seconds": t_parse, "prepare_seconds": t_prepare, "load_seconds": t_parse + t_prepare,
        "load_rss_mib": load_rss, "first_render_seconds": t_first, "repeat_render_seconds": t_repeat,
        "render_seconds": t_render, "samples_per_second": width * height * args.spp / t_render,
    }
    if marginal is not None and args.spp > WARMUP_SPP:
        record["marginal_samples_per_second"] = marginal
    with open(args.mitsuba_child, "w") as f:
        json.dump(record, f, indent=1)
    return 0


def cell(values, form, scale):
    if not values:
        return "—"
    v = sorted(x * scale for x in values)
    return " / ".join(form.format(x) for x in (v[0], statistics.median(v), v[-1]))


def mean_over_runs(records):
    return np.mean([r["mean_rgb"] for r in records], axis=0)


def table(records):
    configs = list(records)
    rows = ["| quantity (min / median / max) | " + " | ".join(label(c, records) for c in configs) + " |",
            "|---" * (len(configs) + 1) + "|"]
    for key, name, form, scale in QUANTITIES:
        cells = [cell([r[key] for r in records[c] if key in r], form, scale) for c in configs]
        if any(c != "—" for c in cells):
            rows.append(f"| {name} | " + " | ".join(cells) + " |")
    means = [fmt(mean_over_runs(records[c]), 4).strip("[]").replace(", ", " / ") for c in configs]
    rows.append("| mean radiance R / G / B (mean of the runs) | " + " | ".join(means) + " |")
    return rows


def label(config, records):
    if config == "instanced":
        return "ours, instanced"
    if config == "flattened":
        return "ours, --flatten-instances"
    return f"Mitsuba 3 {records[config][0]['variant']}"


def block_means(img, size=8):
    h, w = (img.shape[0] // size) * size, (img.shape[1] // size) * size
    return img[:h, :w, :3].astype(np.float64).reshape(h // size, size, w // size, size, 3).mean((1, 3))


def block_rrmse(args, config):
    """Relative RMSE of 8x8-block means of config's first-round image against ours instanced
    (noise plus any misplaced geometry: a check the global means cannot make)."""
    base = block_means(read_exr(paths(args, "instanced", 0)[0]))
    other = block_means(read_exr(paths(args, config, 0)[0]))
    return float(np.sqrt(np.mean((other - base) ** 2)) / np.mean(base))


def agreement(args, records):
    """Lines comparing each configuration's mean radiance with ours instanced; True if all agree."""
    base = mean_over_runs(records["instanced"])
    lines, ok = [], True
    for c in list(records)[1:]:
        rel = mean_over_runs(records[c]) / base - 1.0
        within = bool(np.all(np.abs(rel) <= args.tolerance))
        ok &= within
        lines.append(f"- {label(c, records)} / ours instanced − 1, per channel: {fmt(rel, 4)}"
                     f"{'' if within else f'  ** beyond {100 * args.tolerance:g} % **'}; "
                     f"relative RMSE of 8x8-block means (first round): {block_rrmse(args, c):.4f}")
    return lines, ok


def machine_info():
    model = "?"
    try:
        for line in subprocess.run(["lscpu"], capture_output=True, text=True).stdout.splitlines():
            if line.startswith("Model name:"):
                model = line.split(":", 1)[1].strip()
    except OSError:
        pass
    with open("/proc/meminfo") as f:
        mem_gib = int(f.readline().split()[1]) / 2**20
    return f"{model}, {os.cpu_count()} cores, {mem_gib:.0f} GiB, {platform.system()} {platform.release()}"


def versions(args, records):
    out = subprocess.run([args.render_bin, "--version"], capture_output=True, text=True).stdout.strip()
    commit = subprocess.run(["git", "-C", ROOT, "describe", "--always", "--dirty"], capture_output=True,
                            text=True).stdout.strip()
    mitsuba = [records[c][0] for c in records if c.startswith("mitsuba")]
    threads = f"{records['instanced'][0]['threads']} threads"
    return "; ".join([f"{out} (git {commit}), {threads}"] + [
        f"Mitsuba {m['mitsuba_version']} {m['variant']}, {m['threads']} threads" for m in mitsuba])


def report(args, records, load_before, load_after, elapsed):
    first, flat = records["instanced"][0], records["flattened"][0]
    lines = [
        f"# Scale benchmark ({time.strftime('%Y-%m-%d %H:%M %Z')})",
        "",
        f"Machine: {machine_info()}; load average {load_before:.2f} before, {load_after:.2f} after.",
        "",
        f"Software: {versions(args, records)}.",
        "",
        f"Command: `python3 assets-scripts/{os.path.basename(__file__)} " + " ".join(sys.argv[1:]) + "`",
        "",
        f"Scene: {os.path.relpath(args.scene, ROOT)}, {first['triangle_instances']:,} triangle instances; ours "
        f"stores {first['stored_triangles']:,} triangles and {first['instances']} instances, flattened "
        f"{flat['stored_triangles']:,} triangles. {args.resolution[0]}x{args.resolution[1]}, {args.spp} spp, "
        f"max depth {args.max_depth}; {args.runs} interleaved round(s) in {elapsed:.0f} s.",
        "",
    ]
    lines += table(records)
    agree, ok = agreement(args, records)
    lines += ["", "Mean radiance against ours instanced (means over the rounds):", "", *agree, ""]
    lines.append("parse: ours reading the glTF (+ copying the instances when flattened), Mitsuba loading the "
                 "PLYs; prepare: ours BVHs, materials, lights; Mitsuba `load_dict` of the scene (instances, "
                 "emitters, its Embree BVH build); render: ours `wall_seconds`, Mitsuba the third `mi.render` "
                 f"call of its process (after two at {WARMUP_SPP} spp); samples/s = width·height·spp / render; "
                 "peak RSS of each process by GNU time, after loading by VmHWM.")
    return lines, ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--resolution", type=parse_resolution, default=DEFAULT_RESOLUTION, help="WxH (default 640x360)")
    ap.add_argument("--spp", type=int, default=DEFAULT_SPP)
    ap.add_argument("--runs", type=int, default=DEFAULT_RUNS)
    ap.add_argument("--max-depth", type=int, default=DEFAULT_MAX_DEPTH)
    ap.add_argument("--variant", action="append", default=None,
                    help="Mitsuba variant, repeatable (default: llvm_ad_rgb and scalar_rgb)")
    ap.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE,
                    help="relative mean-radiance difference flagged (default 0.02)")
    ap.add_argument("--scene-dir", default=make_scale_scene.DEFAULT_SCENE_DIR)
    ap.add_argument("--render-bin", default=os.path.join(ROOT, "target", "release", "render"))
    ap.add_argument("--out-dir", default=None, help="images and stats (default SCENE_DIR/benchmark)")
    ap.add_argument("--output", default=None, help="markdown report (default SCENE_DIR/benchmark.md)")
    ap.add_argument("--mitsuba-child", metavar="JSON", help=argparse.SUPPRESS)
    ap.add_argument("--child-exr", help=argparse.SUPPRESS)
    ap.add_argument("--child-seed", type=int, default=0, help=argparse.SUPPRESS)
    args = ap.parse_args()
    args.variant = args.variant or DEFAULT_VARIANTS
    if args.mitsuba_child:
        return mitsuba_child(args)

    args.scene = os.path.join(args.scene_dir, "scene.gltf")
    args.out_dir = args.out_dir or os.path.join(args.scene_dir, "benchmark")
    args.output = args.output or os.path.join(args.scene_dir, "benchmark.md")
    if not os.path.isfile(GNU_TIME):
        sys.exit(f"{GNU_TIME} is missing (apt-get install time): it measures each child's peak RSS")
    if not os.path.isfile(args.scene):
        subprocess.run([sys.executable, os.path.join(os.path.dirname(__file__), "make_scale_scene.py"),
                        args.scene_dir], check=True)
    os.makedirs(args.out_dir, exist_ok=True)

    load_before, start = os.getloadavg()[0], time.perf_counter()
    records = {c: [] for c in OURS + [f"mitsuba-{v}" for v in args.variant]}
    for run in range(args.runs):
        print(f"--- round {run + 1} of {args.runs}", flush=True)
        records["instanced"].append(run_ours(args, False, run))
        records["flattened"].append(run_ours(args, True, run))
        for v in args.variant:
            records[f"mitsuba-{v}"].append(run_mitsuba(args, v, run))
        for c in records:
            r = records[c][-1]
            print(f"{c}: load {r['load_seconds']:.2f} s, render {r['render_seconds']:.2f} s = "
                  f"{r['samples_per_second'] / 1e6:.3f} M samples/s, peak RSS {r['peak_rss_mib']:.0f} MiB, "
                  f"mean RGB {fmt(r['mean_rgb'], 4)}", flush=True)
    elapsed = time.perf_counter() - start
    with open(os.path.join(args.out_dir, "records.json"), "w") as f:
        json.dump(records, f, indent=1)
    lines, ok = report(args, records, load_before, os.getloadavg()[0], elapsed)
    text = "\n".join(lines) + "\n"
    with open(args.output, "w") as f:
        f.write(text)
    print("\n" + text + f"-> {args.output}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
