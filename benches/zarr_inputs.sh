#!/usr/bin/env bash
# Inputs of benches/zarr_whole_process.sh: the demo medallion at SIZE² (a procedural source,
# streamed, so 16384² needs no 6 GB in memory) written by `rgbn eval` as BASE.exr (rgbn's
# default EXR: ZIP, float32) and BASE.zarr (rgbn's default store: float32, zstd, 512-pixel
# chunks, every level).
#
#   benches/zarr_inputs.sh SIZE BASE [RGBN]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
size="$1"; base="$2"; rgbn="${3:-$here/target/release/rgbn}"
# Above 8192² the pixel limit is raised for these runs only (the source streams: no image
# is held whole).
export RGBN_MAX_PIXELS="${RGBN_MAX_PIXELS:-$(( size * size > 134217728 ? size * size : 134217728 ))}"
rm -rf "$base.zarr" "$base.exr"
"$rgbn" eval "$here/benches/zarr_source.ron" --set "source.size=$size" -o "image=$base.exr"
"$rgbn" eval "$here/benches/zarr_source.ron" --set "source.size=$size" -o "image=$base.zarr"
