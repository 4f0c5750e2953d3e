#!/usr/bin/env bash
# OME-Zarr chunk size and compression, measured whole-process (issue 52): for each compression
# (zstd, blosc, none) and chunk side (256, 512, 1024), and rgbn's EXR ZIP as the peer, write
# the image of SRC.exr (`rgbn eval benches/zarr_copy.ron --input image=SRC.exr -o image=…`: the
# EXR's decoding and a normalize, the same for every configuration, then the write; every
# level, as users get it) and read it back whole (`rgbn info …`: load + validate), N rounds, the order of
# the configurations reversed every other round; a `sync` (not timed) before every run. One
# line per run, "who wall user sys peak-RSS-KB" (`python3 benches/medians.py LOG`), then the
# bytes of each (whole store, level 0).
#
#   benches/zarr_format.sh SRC.exr DIR [ROUNDS] [RGBN]   (SRC.exr: benches/zarr_inputs.sh)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
src="$1"; dir="$2"; rounds="${3:-5}"; rgbn="${4:-$here/target/release/rgbn}"
mkdir -p "$dir"
run() { local who=$1; shift; sync; /usr/bin/time -f "$who %e %U %S %M" "$@" 2>&1 >/dev/null | tail -1; }
configs=(exr zstd-256 zstd-512 zstd-1024 blosc-256 blosc-512 blosc-1024 none-256 none-512 none-1024)
one() {
  local c=$1
  if [[ $c == exr ]]; then
    rm -f "$dir/f.exr"
    run "w-exr" "$rgbn" eval "$here/benches/zarr_copy.ron" --input "image=$src" -o "image=$dir/f.exr"
    run "r-exr" "$rgbn" info "$dir/f.exr"
  else
    local comp=${c%-*} chunk=${c#*-}
    rm -rf "$dir/$c.zarr"
    run "w-$c" "$rgbn" eval "$here/benches/zarr_copy.ron" --input "image=$src" \
      --zarr-compression "$comp" --chunk "$chunk" -o "image=$dir/$c.zarr"
    run "r-$c" "$rgbn" info "$dir/$c.zarr"
  fi
}
for i in $(seq "$rounds"); do
  if (( i % 2 )); then for c in "${configs[@]}"; do one "$c"; done
  else for (( k=${#configs[@]}-1; k>=0; k-- )); do one "${configs[$k]}"; done; fi
done
for c in "${configs[@]}"; do
  if [[ $c == exr ]]; then echo "bytes exr $(stat -c %s "$dir/f.exr")"
  else echo "bytes $c $(du -sb --apparent-size "$dir/$c.zarr" | cut -f1) level0 $(du -sb --apparent-size "$dir/$c.zarr/0" | cut -f1)"; fi
done
