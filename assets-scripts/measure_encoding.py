#!/usr/bin/env python3
"""Preview PSNR of encoded materials against their tables, for sparse sample counts and for
refinement steps: what `material-nn encode --model` gives a user who has only a table (or a
few measured samples) and the shipped latent.bin.

For each material, the material-preview scene is rendered once with its MERL table (the
reference) and once per setting with the code `encode --model MODEL --table T --count N
[--refine-steps S]` made; PSNR/SSIM come from `render --reference ... --error-log` (8-bit
display values, as `material-nn eval`). Prints a markdown table per sweep.

Usage (after `cargo build --release` and assets-scripts/make_merl_tables.sh):
    python3 assets-scripts/measure_encoding.py --tables data/merl-fitted \
        --materials brass,red-specular-plastic,orange-paint,gold-metallic-paint2 \
        [--model scenes/materials/latent.bin] [--spp 256] [--out out/encoding] \
        [--counts 100,400,1000,4000,65536] [--steps 0,100,300,1000] \
        [--encode-args "--no-offset --no-residual"]

An empty --counts or --steps skips that sweep; --encode-args are passed to every `encode`
(e.g. "--no-offset --no-residual" for z alone, "--no-residual" for z and offsets).
"""
import argparse
import csv
import json
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
RENDER = ROOT / "target/release/render"
MATERIAL_NN = ROOT / "target/release/material-nn"
SCENE = ROOT / "scenes/material-preview/scene.gltf"


def run(args):
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(map(str, args))}: {done.stderr.strip()}")
    return done.stdout


def render(out, bind, spp, material=None, reference=None):
    args = [RENDER, SCENE, "--spp", spp, "--resolution", "128x128", "--bind", bind,
            "--output", out, "--seed", 7]
    if material:
        args += ["--material", material]
    if reference:
        log = out.with_suffix(".csv")
        args += ["--reference", reference, "--error-log", log]
    run(args)
    if reference:
        rows = list(csv.DictReader(open(log)))
        return float(rows[-1]["psnr"]), float(rows[-1]["ssim"])
    return None


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tables", required=True, type=pathlib.Path)
    p.add_argument("--materials", required=True)
    p.add_argument("--model", type=pathlib.Path, default=ROOT / "scenes/materials/latent.bin")
    p.add_argument("--spp", type=int, default=256)
    p.add_argument("--counts", default="100,400,1000,4000,65536")
    p.add_argument("--steps", default="0,100,300,1000")
    p.add_argument("--out", type=pathlib.Path, default=ROOT / "out/encoding")
    p.add_argument("--encode-args", default="", help="more arguments of every encode")
    a = p.parse_args()
    a.out.mkdir(parents=True, exist_ok=True)
    materials = a.materials.split(",")
    counts = [int(c) for c in a.counts.split(",") if c]
    steps = [int(s) for s in a.steps.split(",") if s]
    references = {}
    for m in materials:
        table = (a.tables / f"{m}.binary").resolve()
        references[m] = a.out / f"{m}-table.exr"
        render(references[m], f"preview=merl:{table}", a.spp)

    def measure(m, count, refine):
        lib = a.out / f"{m}-{count}-{refine}.bin"
        lib.unlink(missing_ok=True)
        steps = [] if refine == "default" else ["--refine-steps", refine]
        info = json.loads(run([MATERIAL_NN, "encode", "--model", a.model, "--table",
                               a.tables / f"{m}.binary", "--count", count, *steps,
                               "--name", m, "--add-to", lib]
                              + a.encode_args.split()))
        psnr, ssim = render(a.out / f"{m}-{count}-{refine}.exr", f"preview={m}", a.spp,
                            material=lib, reference=references[m])
        return psnr, ssim, info["seconds"]

    # encode's default steps depend on the sample count (fewer on sparse sets).
    for title, settings in [
        ("samples (encode's default refinement steps)", [(c, "default") for c in counts]),
        ("refinement steps (65,536 samples)", [(65536, s) for s in steps]),
    ]:
        if not settings:
            continue
        print(f"\n### Preview PSNR (dB) against the table, {a.spp} spp, by {title}\n")
        head = [f"{c} / {s}" for c, s in settings]
        print("| material | " + " | ".join(head) + " |")
        print("| --- |" + " --- |" * len(head))
        sums = [0.0] * len(settings)
        for m in materials:
            cells = []
            for k, (c, s) in enumerate(settings):
                psnr, _, seconds = measure(m, c, s)
                sums[k] += psnr
                cells.append(f"{psnr:.2f} ({seconds:.1f} s)")
            print(f"| {m} | " + " | ".join(cells) + " |", flush=True)
        print("| mean | " + " | ".join(f"{v / len(materials):.2f}" for v in sums) + " |")


if __name__ == "__main__":
    main()
