#!/usr/bin/env bash
# What a neural material costs against the tabulated MERL BSDF of the same material, measured
# in one run (figures are ratios of runs interleaved on the same machine):
#  1. render speed: scenes/material-preview at the same resolution, spp and seed with the
#     sphere bound to (a) the table data/merl-fitted/NAME.binary and (b) the latent code NAME
#     of scenes/materials/latent.bin; min / median / max samples/s of RUNS interleaved runs
#     each, and the ratio of the medians table/neural (the slowdown of the neural BSDF);
#  2. load: load seconds (from --stats) and peak resident memory of a 1-spp 64x64 render
#     binding the code against the same render without any latent file.
# Needs the tables from assets-scripts/make_merl_tables.sh.
#
# Usage: assets-scripts/neural_cost.sh [NAME]   (env: SPP=64 RES=256x256 RUNS=3)
set -euo pipefail
cd "$(dirname "$0")/.."
NAME=${1:-alum-bronze}
SPP=${SPP:-64}
RES=${RES:-256x256}
RUNS=${RUNS:-3}
TABLE=data/merl-fitted/$NAME.binary
LATENT=scenes/materials/latent.bin
SCENE=scenes/material-preview/scene.gltf
[ -f "$TABLE" ] || { echo "error: $TABLE missing: run assets-scripts/make_merl_tables.sh" >&2; exit 2; }
cargo build --release -q -p render-cli --bin render
RENDER=target/release/render
OUT=$(mktemp -d)
trap 'rm -rf "$OUT"' EXIT

field() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])" "$1" "$2"; }

tables=()
neurals=()
for i in $(seq "$RUNS"); do
    "$RENDER" "$SCENE" --bind "preview=merl:$TABLE" --spp "$SPP" --resolution "$RES" --output "$OUT/t.exr" --stats "$OUT/t.json" 2>/dev/null
    "$RENDER" "$SCENE" --material "$LATENT" --bind "preview=$NAME" --spp "$SPP" --resolution "$RES" --output "$OUT/n.exr" --stats "$OUT/n.json" 2>/dev/null
    tables+=("$(field "$OUT/t.json" samples_per_second)")
    neurals+=("$(field "$OUT/n.json" samples_per_second)")
done
python3 - "${tables[*]}" "${neurals[*]}" <<PY
import statistics, sys
t, n = ([float(v) / 1e6 for v in a.split()] for a in sys.argv[1:3])
fmt = lambda v: f"{min(v):.3f} / {statistics.median(v):.3f} / {max(v):.3f}"
print(f"render $NAME, $RES, $SPP spp, {len(t)} interleaved runs, M samples/s min / median / max:")
print(f"  table {fmt(t)}; neural {fmt(n)}; neural is {statistics.median(t) / statistics.median(n):.2f}x slower (medians)")
PY

measure() {  # prints: load_seconds peak_kb
    /usr/bin/time -f "%M" -o "$OUT/mem" "$RENDER" "$SCENE" "$@" --spp 1 --resolution 64x64 --output "$OUT/m.exr" --stats "$OUT/m.json" 2>/dev/null
    echo "$(field "$OUT/m.json" load_seconds) $(cat "$OUT/mem")"
}
read -r load_plain mem_plain < <(measure --bind "preview=merl:$TABLE")
read -r load_neural mem_neural < <(measure --material "$LATENT" --bind "preview=$NAME")
read -r load_none mem_none < <(measure)
python3 -c "
print(f'load with 1 code of $LATENT: {$load_neural:.3f} s, peak {$mem_neural/1024:.1f} MB')
print(f'load without a latent file (glTF material): {$load_none:.3f} s, peak {$mem_none/1024:.1f} MB')
print(f'load with the MERL table instead: {$load_plain:.3f} s, peak {$mem_plain/1024:.1f} MB')
print(f'neural material costs +{$load_neural-$load_none:.3f} s and +{($mem_neural-$mem_none)/1024:.1f} MB over the scene without one')"
