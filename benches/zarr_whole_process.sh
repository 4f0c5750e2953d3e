#!/usr/bin/env bash
# Whole-process `rgbn eval graphs/input_image.ron` with input and output as OME-Zarr (zstd,
# rgbn's default store options) against the same image as EXR ZIP in and out (issue 52), the
# two alternated (the order swapped every round), N rounds. A `sync` (not timed) before every
# run and the previous run's output removed (not timed), so no run pays for another's dirty
# pages or for replacing its output. One line per run, "who wall user sys peak-RSS-KB"
# (`python3 benches/medians.py LOG` prints the medians), then the bytes of the inputs and of
# the last outputs.
#
#   benches/zarr_whole_process.sh BASE [ROUNDS] [RGBN] [-- EXTRA rgbn eval ARGS]
#
# BASE.zarr and BASE.exr: the same RGBN image as a store and as an EXR (benches/zarr_inputs.sh
# makes them); RGBN: the binary (default target/release/rgbn). Outputs go to a temporary
# folder beside BASE (the same disk).
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
base="$1"; rounds="${2:-5}"
rgbn="${3:-$here/target/release/rgbn}"
shift $(( $# < 3 ? $# : 3 ))
[[ "${1:-}" == "--" ]] && shift
extra=("$@")
out="$(mktemp -d "$(dirname "$base")/zwp.XXXXXX")"
trap 'rm -rf "$out"' EXIT
run() { local who=$1; shift; sync; /usr/bin/time -f "$who %e %U %S %M" "$@" 2>&1 >/dev/null | tail -1; }
g="$here/graphs/input_image.ron"
zarr() { rm -rf "$out/o.zarr"; run zarr "$rgbn" eval "$g" --input "image=$base.zarr" -o "image=$out/o.zarr" "${extra[@]}"; }
exr() { rm -f "$out/o.exr"; run exr "$rgbn" eval "$g" --input "image=$base.exr" -o "image=$out/o.exr" "${extra[@]}"; }
for i in $(seq "$rounds"); do
  if (( i % 2 )); then zarr; exr; else exr; zarr; fi
done
size() { du -sb --apparent-size "$1" | cut -f1; }
echo "bytes in.zarr $(size "$base.zarr") in.exr $(size "$base.exr") out.zarr $(size "$out/o.zarr") out.exr $(size "$out/o.exr")"
echo "bytes level0 in.zarr $(size "$base.zarr/0") out.zarr $(size "$out/o.zarr/0")"
