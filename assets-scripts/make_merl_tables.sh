#!/usr/bin/env bash
# Makes the MERL-layout tables the project trains and tests on, from the shared NBRDF networks
# fitted to the 100 MERL materials (the MERL files themselves are not redistributable):
#   data/merl-fitted/NAME.binary   100 tables, 34,992,012 bytes each (3.5 GB in all)
#   data/merl-median.binary        their per-bin median (f_ref of the log-relative mapping)
#   data/synthetic/*.binary        a small family from analytic models, for tests
#   data/rgl-fitted/NAME.binary    the 51 RGL and data/nielsen-fitted the 8 Nielsen materials
#                                  (never trained on: the out-of-distribution test of encoding)
# data/ is git-ignored. Safe to interrupt and re-run: tables already present are skipped and
# every file is written atomically.
#
# Usage: assets-scripts/make_merl_tables.sh [NBRDF_MERL_DIR]   (default ../shared/data/nbrdf/merl)
set -euo pipefail
cd "$(dirname "$0")/.."
nbrdf_dir="${1:-../shared/data/nbrdf/merl}"

cargo build --release -p material-nn
bin=target/release/material-nn

"$bin" tabulate --nbrdf "$nbrdf_dir" --out data/merl-fitted
if [ ! -f data/merl-median.binary ]; then
    "$bin" tabulate --median-of data/merl-fitted --out data/merl-median.binary
fi

shared_nbrdf="$(dirname "$nbrdf_dir")"
for set in rgl-isotropic:rgl-fitted nielsen:nielsen-fitted; do
    if [ -d "$shared_nbrdf/${set%%:*}" ]; then
        "$bin" tabulate --nbrdf "$shared_nbrdf/${set%%:*}" --out "data/${set##*:}"
    fi
done

mkdir -p data/synthetic
make_synthetic() {
    local out="data/synthetic/$1.binary"
    shift
    [ -f "$out" ] || "$bin" tabulate "$@" --out "$out"
}
for alpha in 0.05 0.2 0.5; do
    make_synthetic "ggx-$alpha" --analytic ggx --albedo 0.4,0.2,0.1 --specular 0.04 --alpha "$alpha"
    make_synthetic "beckmann-$alpha" --analytic beckmann --albedo 0.1,0.3,0.5 --specular 0.9,0.6,0.3 --alpha "$alpha"
    make_synthetic "ward-$alpha" --analytic ward --albedo 0.3 --specular 0.2 --alpha "$alpha"
done
for sigma in 0.0 0.3 0.6; do
    make_synthetic "oren-nayar-$sigma" --analytic oren-nayar --albedo 0.7,0.5,0.3 --sigma "$sigma"
done
