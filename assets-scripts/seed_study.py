#!/usr/bin/env python3
"""FreNBRDF against HyperBRDF over several seeds: the analogues of the talk's Table 1
(reconstruction of the test materials) and Table 2 (editing: random pairs of test materials
interpolated in latent space), as mean ± standard deviation over the seeds of every column.

For each model (scenes/materials/frenbrdf.json, scenes/materials/hyperbrdf.json: the same
configuration without L_fre) and seed, trains runs/seed-study/MODEL-sSEED with the seed and
epoch count overridden, then `material-nn eval` on its test split (the seed also draws the
split, so the two models of one seed see the same materials). Seeds go in order, both models
of a seed one after the other, so a partial study is still paired.

The study takes hours (about 43 min per run on a 2-core machine), more than one sitting: each
finished run's results — the per-material reconstruction CSV and the means of both tables —
go to docs/seed-study/ (small, committed), and a run with results there is not trained again.
Runs and evaluations under --out are kept too (checkpoints resume per epoch), so the script
resumes where it stopped on the same machine, and where the last committed run ended on a
fresh checkout. The tables are printed and written to docs/seed-study/tables.md.

--split-seed N holds the split fixed (the configuration's `split_seed`): the seeds then vary
only the initial weights and samples, every run is tested on the same materials, and the
spread over seeds is the models' alone. Such runs are named MODEL-eE-sSEED-splitN-... and
their tables go to docs/seed-study/tables-splitN.md; seed N itself is the study's run of seed N.

--models names the configurations of scenes/materials/ to study (default: frenbrdf hyperbrdf,
the talk's recipe and its baseline); the paired differences compare the first two. Studies of
other models write their tables to docs/seed-study/tables-MODEL[-MODEL...].md, for example the
shipped recipe alone: --models frenbrdf-interpolation.

    python3 assets-scripts/seed_study.py [--seeds 1 2 3] [--epochs 100] [--spp 1024] [--pairs 2000]
    python3 assets-scripts/seed_study.py --split-seed 3 --seeds 4 5 --pairs 200
    python3 assets-scripts/seed_study.py --models frenbrdf-interpolation
"""

import argparse
import csv
import fcntl
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BIN = ROOT / "target" / "release" / "material-nn"
COLUMNS = [("rmse", "RMSE×10²", 100.0), ("rec", "L_rec data ×10²", 100.0), ("fre", "L_fre×10³", 1000.0),
           ("psnr", "PSNR (dB)", 1.0), ("ssim", "SSIM×10", 10.0)]


def run(cmd: list[str], log: Path) -> None:
    with log.open("w") as f:
        if subprocess.run(cmd, stdout=f, stderr=subprocess.STDOUT).returncode != 0:
            sys.exit(f"error: {' '.join(cmd)} failed; see {log}")


def means(path: Path) -> dict[str, float]:
    """Mean of each column over the rows of an eval CSV (empty cells left out)."""
    rows = list(csv.DictReader(path.open()))
    out = {}
    for key, _, _ in COLUMNS:
        values = [float(r[key]) for r in rows if r.get(key)]
        if values:
            out[key] = statistics.fmean(values)
    out["n"] = len(rows)
    if rows and rows[0].get("psnr"):
        out["worst_psnr"] = min(float(r["psnr"]) for r in rows)
    return out


def machine() -> str:
    """The CPU model and the cores this process may use, for the record of a run."""
    model = platform.machine()
    try:
        model = next(line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return f"{model}, {len(os.sched_getaffinity(0))} cores"


def cell(values: list[float], scale: float) -> str:
    if not values:
        return "–"
    m = statistics.fmean(values) * scale
    s = statistics.stdev(values) * scale if len(values) > 1 else 0.0
    return f"{m:.3f} ± {s:.3f}"


def stem(model: str, seed: int, args: argparse.Namespace) -> str:
    """The name of a run's results in RESULTS (without extension)."""
    split = "" if args.split_seed in (None, seed) else f"-split{args.split_seed}"
    return f"{model}-e{args.epochs}-s{seed}{split}-spp{args.spp}-pairs{args.pairs}"


DEFAULT_MODELS = ["frenbrdf", "hyperbrdf"]


def tables_path(args: argparse.Namespace) -> Path:
    name = "tables" if args.models == DEFAULT_MODELS else "tables-" + "-".join(args.models)
    return args.results / (f"{name}.md" if args.split_seed is None else f"{name}-split{args.split_seed}.md")


def write_tables(results: dict[str, list[tuple[dict, dict]]], args: argparse.Namespace) -> None:
    """Prints the two tables over the runs done so far and writes them to RESULTS/tables.md."""
    lines = []
    header = "| model | seeds | " + " | ".join(label for _, label, _ in COLUMNS) + " | worst PSNR (dB) |"
    rule = "|" + " --- |" * (len(COLUMNS) + 3)
    for title, index in [("Table 1 analogue: reconstruction of the test materials", 0),
                         ("Table 2 analogue: editing, random pairs of test materials", 1)]:
        split = "" if args.split_seed is None else f", split of seed {args.split_seed} for all"
        lines += [f"\n{title} ({args.epochs} epochs, previews at {args.spp} spp, {args.pairs} pairs{split}; "
                  f"mean ± std over the seeds done of {', '.join(map(str, args.seeds))})\n", header, rule]
        for model, rows in results.items():
            tables = [r[index] for r in rows]
            cells = [cell([t[k] for t in tables if k in t], scale) for k, _, scale in COLUMNS]
            worst = cell([t["worst_psnr"] for t in tables if "worst_psnr" in t], 1.0)
            lines.append(f"| {model} | {len(tables)} | " + " | ".join(cells) + f" | {worst} |")
    lines += paired(args)
    text = "\n".join(lines).lstrip() + "\n"
    print(text)
    tables_path(args).write_text(text)


def sign_test(wins: int, n: int) -> float:
    """Two-sided p-value of `wins` of `n` under a fair coin (exact binomial)."""
    k = min(wins, n - wins)
    return min(1.0, 2.0 * sum(math.comb(n, i) for i in range(k + 1)) / 2.0 ** n)


def paired(args: argparse.Namespace) -> list[str]:
    """The first two models paired on the seeds both finished (same split, same test
    materials): per seed, the differences of the tables' means; over every material of every
    such seed, the mean PSNR difference ± its standard error, the materials the first renders
    better, and the sign test of that count."""
    if len(args.models) < 2:
        return []
    first, second = args.models[:2]
    rows, diffs = [], []
    for seed in args.seeds:
        kept = [args.results / f"{stem(m, seed, args)}.json" for m in (first, second)]
        if not all(k.exists() for k in kept):
            continue
        fre, hyper = (json.loads(k.read_text()) for k in kept)
        d = lambda table, key, scale: (fre[table][key] - hyper[table][key]) * scale
        rows.append(f"| {seed} | {d('reconstruction', 'psnr', 1):+.2f} | {d('reconstruction', 'worst_psnr', 1):+.2f} | "
                    f"{d('reconstruction', 'rec', 100):+.3f} | {d('reconstruction', 'fre', 1000):+.3f} | "
                    f"{d('editing', 'rec', 100):+.3f} | {d('editing', 'fre', 1000):+.3f} |")
        psnr = [{r["name"]: float(r["psnr"]) for r in csv.DictReader((args.results / f"{stem(m, seed, args)}-reconstruction.csv").open())}
                for m in (first, second)]
        diffs += [psnr[0][name] - psnr[1][name] for name in psnr[0] if name in psnr[1]]
    if not rows:
        return []
    lines = [f"\nPaired by seed, {first} − {second} (positive PSNR and negative losses favour {first})\n",
             "| seed | PSNR (dB) | worst PSNR (dB) | L_rec data ×10² | L_fre×10³ | editing L_rec ×10² | editing L_fre×10³ |",
             "|" + " --- |" * 7, *rows]
    wins = sum(x > 0 for x in diffs)
    se = statistics.stdev(diffs) / math.sqrt(len(diffs)) if len(diffs) > 1 else 0.0
    lines.append(f"\nOver {len(diffs)} material-seed pairs: PSNR difference {statistics.fmean(diffs):+.2f} ± {se:.2f} dB "
                 f"(mean ± standard error); {first} better on {wins} of {len(diffs)} "
                 f"(sign test, two-sided p = {sign_test(wins, len(diffs)):.2f}).")
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--epochs", type=int, default=100)
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--pairs", type=int, default=2000)
    ap.add_argument("--models", nargs="+", default=DEFAULT_MODELS,
                    help="configurations of scenes/materials/ (without .json); the first two are paired")
    ap.add_argument("--split-seed", type=int, default=None,
                    help="hold the split fixed at this seed's (default: each seed draws its own)")
    ap.add_argument("--data", type=Path, default=ROOT / "data" / "merl-fitted")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "seed-study")
    ap.add_argument("--results", type=Path, default=ROOT / "docs" / "seed-study",
                    help="where each finished run's results are kept (committed)")
    args = ap.parse_args()
    for model in args.models:
        if not (ROOT / "scenes" / "materials" / f"{model}.json").is_file():
            sys.exit(f"error: scenes/materials/{model}.json: no such configuration (--models)")
    subprocess.run(["cargo", "build", "--release", "-p", "material-nn"], cwd=ROOT, check=True)
    args.out.mkdir(parents=True, exist_ok=True)
    args.results.mkdir(parents=True, exist_ok=True)
    # Two studies on one directory would resume the same run twice at once.
    lock = (args.out / "study.lock").open("w")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        sys.exit(f"error: {args.out}: another seed study is running on it")
    references = args.out / "table-renders"
    if references.exists() and references.stat().st_mtime < BIN.stat().st_mtime:
        shutil.rmtree(references)
    results: dict[str, list[tuple[dict, dict]]] = {}
    for seed in args.seeds:
        for model in args.models:
            kept = args.results / f"{stem(model, seed, args)}.json"
            if kept.exists():
                means_of = json.loads(kept.read_text())
                results.setdefault(model, []).append((means_of["reconstruction"], means_of["editing"]))
                continue
            name = f"{model}-e{args.epochs}-s{seed}" + ("" if args.split_seed in (None, seed) else f"-split{args.split_seed}")
            run_dir = args.out / name
            config = json.loads((ROOT / "scenes" / "materials" / f"{model}.json").read_text())
            config.update(seed=seed, epochs=args.epochs)
            if args.split_seed is not None:
                config.update(split_seed=args.split_seed)
            config_path = args.out / f"{name}.json"
            config_path.write_text(json.dumps(config, indent=2))
            # A finished run resumes to its end at once; an interrupted one goes on.
            resume = ["--resume"] if (run_dir / "checkpoint.bin").exists() else ["--config", str(config_path)]
            print(f"training {name}", file=sys.stderr)
            run([str(BIN), "train", "--data", str(args.data), "--out", str(run_dir), *resume],
                args.out / f"{name}.train.log")
            eval_dir = run_dir / f"eval-spp{args.spp}-pairs{args.pairs}"
            if not (eval_dir / "summary.md").exists():
                print(f"evaluating {name}", file=sys.stderr)
                # Both models of a seed have the same test materials: the tables' renders are
                # made once (the cache is for this build; cleared when the binary is newer).
                run([str(BIN), "eval", "--run", str(run_dir), "--spp", str(args.spp), "--pairs", str(args.pairs),
                     "--out", str(eval_dir), "--reference-cache", str(references)], args.out / f"{name}.eval.log")
            table1, table2 = means(eval_dir / "reconstruction.csv"), means(eval_dir / "editing.csv")
            shutil.copyfile(eval_dir / "reconstruction.csv", args.results / f"{kept.stem}-reconstruction.csv")
            # Written last and atomically: its presence marks the run as done.
            tmp = kept.with_suffix(".json.tmp")
            tmp.write_text(json.dumps({"model": model, "seed": seed, "epochs": args.epochs, "spp": args.spp,
                                       "pairs": args.pairs, "machine": machine(),
                                       "reconstruction": table1, "editing": table2}, indent=2) + "\n")
            tmp.replace(kept)
            results.setdefault(model, []).append((table1, table2))
            write_tables(results, args)
    write_tables(results, args)


if __name__ == "__main__":
    main()
