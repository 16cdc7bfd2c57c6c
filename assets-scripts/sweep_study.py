#!/usr/bin/env python3
"""Editing sweeps against the table blend, over many pairs (issue 49's figures).

For each pair A:B, `render --sweep A:B:5 --tables DIR` renders the material preview with the
decoded codes at t = 0, 0.25, 0.5, 0.75, 1 and with the linear blend of the two tables at the
same t, and writes PSNR and SSIM of every frame against its table frame (sweep.csv). This
script collects the interior frames (t = 0.25, 0.5, 0.75) of every pair and adds the sphere's
mean radiance (the pixels whose centre ray passes within 0.95 of the sphere's radius of its
centre, compare_preview_mitsuba.sphere_mask) of each frame against the darker end's: an
energy dip shows as a ratio below 1.

Pairs default to those of `render energy --list-pairs` (docs/training.md, "Editing": metal <->
metal, metal <-> fabric, paint <-> plastic and others) whose two tables are in --tables (with
the MERL tables: the 25 MERL pairs). Resumable: a pair whose sweep.csv exists is not rendered
again (delete its directory to redo it).

Usage:
    python3 assets-scripts/sweep_study.py --material scenes/materials/latent.bin \\
        --tables data/merl-fitted --spp 1024 --out data/sweep-study/shipped \\
        [--sheet docs/images/editing-sweeps.png]
Writes OUT/PAIR/ (frames, sweep.csv, contact-sheet.png), OUT/frames.csv and OUT/summary.md;
with --sheet, the contact sheets of --sheet-pairs (neural row over table-blend row) stacked
into one PNG (the image in docs/training.md, "Editing").
Needs numpy and OpenEXR (or Mitsuba 3) to read the frames, Pillow for --sheet.
"""

import argparse
import csv
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_cycles import read_exr  # noqa: E402
from compare_preview_mitsuba import sphere_mask  # noqa: E402

FRAMES = 5
# The three pairs: metal to held-out chrome, fabric to metal, plastic to paint.
SHEET_PAIRS = ("alum-bronze:chrome", "blue-fabric:nickel", "red-plastic:gold-paint")
SCENE = "scenes/material-preview/scene.gltf"


def render_pair(args, pair, out):
    if os.path.exists(os.path.join(out, "sweep.csv")):
        return
    cmd = [args.render, SCENE, "--material", args.material, "--sweep", f"{pair}:{FRAMES}",
           "--tables", args.tables, "--spp", str(args.spp), "--resolution",
           f"{args.size}x{args.size}", "--seed", str(args.seed), "--output", out]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)


def luminance(rgb):
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


def pair_rows(out, pair, mask):
    with open(os.path.join(out, "sweep.csv")) as f:
        errors = {int(r["frame"]): r for r in csv.DictReader(f)}
    radiance = [luminance(read_exr(os.path.join(out, f"frame-{k:03}.exr")))[mask].mean()
                for k in range(FRAMES)]
    table = [luminance(read_exr(os.path.join(out, f"table-{k:03}.exr")))[mask].mean()
             for k in range(FRAMES)]
    darker = min(radiance[0], radiance[-1])
    for k in range(1, FRAMES - 1):
        e = errors[k]
        yield {"pair": pair, "t": float(e["t"]), "psnr": float(e["psnr"]),
               "ssim": float(e["ssim"]), "radiance_vs_darker_end": radiance[k] / darker,
               "radiance_vs_table_blend": radiance[k] / table[k]}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--material", default="scenes/materials/latent.bin")
    p.add_argument("--tables", default="data/merl-fitted")
    p.add_argument("--pairs", help="A:B,C:D,... (default: render energy's pairs with both tables)")
    p.add_argument("--spp", type=int, default=1024)
    p.add_argument("--size", type=int, default=128, help="image width and height")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--render", default="target/release/render")
    p.add_argument("--out", required=True)
    p.add_argument("--sheet", help="PNG: the contact sheets of --sheet-pairs stacked")
    p.add_argument("--sheet-pairs", default=",".join(SHEET_PAIRS), help="A:B,C:D,... for --sheet")
    args = p.parse_args()
    mask = sphere_mask(args.size, args.size)
    rows = []
    if args.pairs:
        pairs = [q for q in args.pairs.split(",") if q]
    else:
        listed = subprocess.run([args.render, "energy", "--list-pairs"], check=True, capture_output=True,
                                text=True).stdout.split()
        pairs = [q for q in listed
                 if all(os.path.exists(os.path.join(args.tables, f"{m}.binary")) for m in q.split(":"))]
    for i, pair in enumerate(pairs):
        out = os.path.join(args.out, pair.replace(":", "--"))
        print(f"[{i + 1}/{len(pairs)}] {pair}", file=sys.stderr, flush=True)
        render_pair(args, pair, out)
        rows.extend(pair_rows(out, pair, mask))
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "frames.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    psnr = np.array([r["psnr"] for r in rows])
    ssim = np.array([r["ssim"] for r in rows])
    dip = np.array([r["radiance_vs_darker_end"] for r in rows])
    worst = min(rows, key=lambda r: r["psnr"])
    lowest = min(rows, key=lambda r: r["radiance_vs_darker_end"])
    lines = [
        f"# Sweeps against the table blend: {args.material}",
        "",
        f"{len(pairs)} pairs, interior frames t = 0.25, 0.5, 0.75; material preview "
        f"{args.size}², {args.spp} spp, seed {args.seed}.",
        "",
        f"- PSNR: mean {psnr.mean():.2f} dB, median {np.median(psnr):.2f}, worst {psnr.min():.2f} "
        f"({worst['pair']}, t = {worst['t']})",
        f"- SSIM: mean {ssim.mean():.4f}, worst {ssim.min():.4f}",
        f"- sphere radiance / darker end: median {np.median(dip):.3f}, worst {dip.min():.3f} "
        f"({lowest['pair']}, t = {lowest['t']}); frames below 0.95: {(dip < 0.95).sum()} of {len(dip)}",
        "",
        "| pair | PSNR t=0.25 / 0.5 / 0.75 | SSIM (worst) | radiance / darker end (worst) | radiance / table blend (worst) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for pair in pairs:
        r = [x for x in rows if x["pair"] == pair]
        lines.append(
            f"| {pair.replace(':', ' → ')} | " + " / ".join(f"{x['psnr']:.1f}" for x in r)
            + f" | {min(x['ssim'] for x in r):.4f} | {min(x['radiance_vs_darker_end'] for x in r):.3f}"
            + f" | {min(x['radiance_vs_table_blend'] for x in r):.3f} |")
    with open(os.path.join(args.out, "summary.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines[4:8]))
    if args.sheet:
        stack_sheets(args.out, [q for q in args.sheet_pairs.split(",") if q], args.sheet)


def stack_sheets(out, pairs, path):
    """The pairs' contact sheets (render --sweep's, neural over table) one above the other."""
    from PIL import Image

    sheets = [Image.open(os.path.join(out, q.replace(":", "--"), "contact-sheet.png")).convert("RGB")
              for q in pairs]
    width = max(s.width for s in sheets)
    stacked = Image.new("RGB", (width, sum(s.height for s in sheets)), (24, 24, 24))
    y = 0
    for s in sheets:
        stacked.paste(s, (0, y))
        y += s.height
    stacked.save(path, optimize=True)
    print(f"{path}: {len(sheets)} contact sheets")


if __name__ == "__main__":
    main()
