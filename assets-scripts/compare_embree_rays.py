#!/usr/bin/env python3
"""Closest-hit throughput on rays leaving a scene's surfaces: our BVH (single rays and packets
of 16, one thread) against Embree as Mitsuba 3 runs it (`llvm_ad_rgb`: Dr.Jit hands Embree
packets of 16; one thread), on the very same triangles and rays.

The rays are those of the `bvh` bench's "closest hit from surfaces" (uniform points of
uniformly chosen triangles, 10⁻⁴ off the surface, uniform directions in the normal's
hemisphere), written by `cargo run --release -p renderer --example surface_rays`. Each run
measures both sides (best of several passes each); --runs runs are interleaved and quoted as
min / median / max. Compare ratios taken in one run: these machines are shared and noisy.

    python3 assets-scripts/compare_embree_rays.py [--scene scenes/material-preview/scene.gltf] [--runs 3]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_mitsuba import set_variant  # noqa: E402


def ours(scene, out_dir, rays):
    cmd = ["cargo", "run", "--release", "-q", "-p", "renderer", "--example", "surface_rays", "--", scene, out_dir, str(rays)]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"error: {' '.join(cmd)}: {done.stderr.strip()}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def embree(mi, dr, out_dir, passes=7):
    """Rays per second of Mitsuba's scene.ray_intersect_preliminary (best of `passes`) and its hits."""
    tris = np.fromfile(os.path.join(out_dir, "triangles.f32"), dtype=np.float32).reshape(-1, 3)
    rays = np.fromfile(os.path.join(out_dir, "rays.f32"), dtype=np.float32).reshape(-1, 6)
    mesh = mi.Mesh("surface", vertex_count=len(tris), face_count=len(tris) // 3, has_vertex_normals=False)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(tris.ravel())
    params["faces"] = mi.UInt32(np.arange(len(tris), dtype=np.uint32))
    params.update()
    scene = mi.load_dict({"type": "scene", "surface": mesh})
    ray = mi.Ray3f(mi.Point3f(*[mi.Float(rays[:, i]) for i in range(3)]),
                   mi.Vector3f(*[mi.Float(rays[:, i]) for i in range(3, 6)]))
    best = float("inf")
    for _ in range(passes):
        dr.eval(ray)
        dr.sync_thread()
        start = time.perf_counter()
        found = scene.ray_intersect_preliminary(ray)
        dr.eval(found.t)
        dr.sync_thread()
        best = min(best, time.perf_counter() - start)
    return len(rays) / best, int(dr.count(found.is_valid())[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default=os.path.join(ROOT, "scenes", "material-preview", "scene.gltf"))
    ap.add_argument("--rays", type=int, default=1 << 16)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    mi = set_variant("llvm_ad_rgb")
    import drjit as dr
    dr.set_thread_count(1)
    rows = []
    with tempfile.TemporaryDirectory() as out_dir:
        for _ in range(args.runs):
            o = ours(os.path.abspath(args.scene), out_dir, args.rays)
            e, e_hits = embree(mi, dr, out_dir)
            rows.append((o["single_rays_per_s"] / 1e6, o["packet_rays_per_s"] / 1e6, e / 1e6))
            print(f"ours single {rows[-1][0]:.2f}, packets {rows[-1][1]:.2f}; Embree ({mi.variant()}) "
                  f"{rows[-1][2]:.2f} M rays/s; hits {o['hits']} / {e_hits} of {o['rays']}", flush=True)
    fmt = lambda v: f"{min(v):.2f} / {statistics.median(v):.2f} / {max(v):.2f}"
    single, packets, emb = zip(*rows)
    best_ours = [max(s, p) for s, p, _ in rows]
    print(f"{os.path.relpath(args.scene, ROOT)}: {o['triangles']} triangles, {args.rays} rays from its surfaces, one thread, "
          f"M rays/s min / median / max of {args.runs}:")
    print(f"  ours single rays {fmt(single)}, packets {fmt(packets)}; Embree {fmt(emb)}; "
          f"Embree / our faster mode {fmt([e / b for e, b in zip(emb, best_ours)])}")


if __name__ == "__main__":
    main()
