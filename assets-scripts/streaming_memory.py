#!/usr/bin/env python3
"""Peak memory of `material-nn train` on a large training set, tables streamed or resident.

Makes (once, into the git-ignored data/large-set/) a training set of the 100 MERL-fitted
tables (links to data/merl-fitted, made by assets-scripts/make_merl_tables.sh) plus N analytic
variations (GGX, Beckmann, Ward and Oren-Nayar lobes with parameters drawn from --seed; 35 MB
each), then trains one epoch of the shipped configuration on it with each --table-cache-mb
given and reports wall time and peak resident memory (GNU time). Streaming changes nothing
in the result: the script checks that every run's first-epoch losses are equal.

    python3 assets-scripts/streaming_memory.py [--variations 200] [--caches 1024 100000]
"""

import argparse
import json
import random
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BIN = ROOT / "target" / "release" / "material-nn"


def variation(rng: random.Random) -> list[str]:
    """Arguments of `material-nn tabulate --analytic` for one random material."""
    kind = rng.choice(["ggx", "ggx", "beckmann", "ward", "oren-nayar"])
    rgb = lambda lo, hi: ",".join(f"{rng.uniform(lo, hi):.3f}" for _ in range(3))
    args = ["--analytic", kind, "--albedo", rgb(0.02, 0.8)]
    if kind == "oren-nayar":
        return args + ["--sigma", f"{rng.uniform(0.05, 1.0):.3f}"]
    metal = rng.random() < 0.3
    specular = rgb(0.4, 0.95) if metal else f"{rng.uniform(0.02, 0.08):.3f}"
    return args + ["--specular", specular, "--alpha", f"{rng.uniform(0.03, 0.6):.3f}"]


def make_set(data: Path, variations: int, seed: int) -> None:
    merl = ROOT / "data" / "merl-fitted"
    tables = sorted(merl.glob("*.binary"))
    if len(tables) != 100:
        sys.exit(f"error: {merl}: expected the 100 MERL-fitted tables (assets-scripts/make_merl_tables.sh)")
    data.mkdir(parents=True, exist_ok=True)
    for t in tables:
        link = data / t.name
        if not link.exists():
            link.symlink_to(t)
    rng = random.Random(seed)
    for k in range(variations):
        args = variation(rng)  # drawn for every k, so the set does not depend on what exists
        out = data / f"variation-{k:04d}.binary"
        if not out.exists():
            subprocess.run([str(BIN), "tabulate", *args, "--out", str(out)], check=True, capture_output=True)
        print(f"\rvariations: {k + 1}/{variations}", end="", file=sys.stderr)
    print(file=sys.stderr)


def train_once(data: Path, cache_mb: int, config: Path) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        cmd = ["/usr/bin/time", "-v", str(BIN), "train", "--data", str(data), "--out", str(run),
               "--config", str(config), "--table-cache-mb", str(cache_mb)]
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            sys.exit(f"error: training with --table-cache-mb {cache_mb} failed:\n{p.stderr[-2000:]}")
        rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr).group(1))
        wall = re.search(r"Elapsed \(wall clock\) time .*: (\S+)", p.stderr).group(1)
        epoch = re.search(r"epoch +1: (.*?), [\d.]+ s", p.stdout)
        return {"cache_mb": cache_mb, "peak_rss_mb": rss_kb / 1024, "wall": wall,
                "epoch_1": epoch.group(1) if epoch else "?"}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--variations", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--caches", type=int, nargs="+", default=[100000, 1024],
                    help="--table-cache-mb values to try (100000: every table resident)")
    ap.add_argument("--data", type=Path, default=ROOT / "data" / "large-set")
    ap.add_argument("--keep", action="store_true", help="keep the variations (7 GB for 200)")
    args = ap.parse_args()
    subprocess.run(["cargo", "build", "--release", "-p", "material-nn"], cwd=ROOT, check=True)
    make_set(args.data, args.variations, args.seed)
    shipped = json.loads((ROOT / "scenes" / "materials" / "frenbrdf.json").read_text())
    shipped["epochs"] = 1
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(shipped, f)
        config = Path(f.name)
    results = [train_once(args.data, c, config) for c in args.caches]
    n = len(list(args.data.glob("*.binary")))
    print(f"{n} tables, one epoch of scenes/materials/frenbrdf.json:")
    print("| --table-cache-mb | peak RSS (MiB) | wall | epoch 1 |")
    print("| --- | --- | --- | --- |")
    for r in results:
        print(f"| {r['cache_mb']} | {r['peak_rss_mb']:.0f} | {r['wall']} | {r['epoch_1']} |")
    if len({r["epoch_1"] for r in results}) != 1:
        sys.exit("error: the runs' losses differ")
    if not args.keep:
        shutil.rmtree(args.data)


if __name__ == "__main__":
    main()
