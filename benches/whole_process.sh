#!/usr/bin/env bash
# Whole-process timing of `rgbn eval graphs/input_image.ron` against its peer
# (../shared/peers/peer_graph.py), alternated, N rounds: one line per run,
# "who wall user sys peak-RSS-KB". Medians go to BENCHMARKS.md.
#
#   benches/whole_process.sh N4K.png [ROUNDS] [PYTHON]
#
# N4K.png: a 3840×2160 16-bit normal map (benches/make_big_png.py); PYTHON: an interpreter
# with numpy, opencv-python and OpenEXR (default python3). RAYON_NUM_THREADS,
# RGBN_HUGE_PAGES=0 and RGBN_KEEP_FREED=0 pass through to rgbn.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
input="$1"; rounds="${2:-5}"; py="${3:-python3}"
rgbn="$here/target/release/rgbn"
peer="$here/../shared/peers/peer_graph.py"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
for _ in $(seq "$rounds"); do
  /usr/bin/time -f "rgbn %e %U %S %M" "$rgbn" eval "$here/graphs/input_image.ron" \
    --input "image=$input" -o "relit=$out/r.png" -o "image=$out/i.exr" 2>&1 >/dev/null | tail -1
  /usr/bin/time -f "peer %e %U %S %M" "$py" "$peer" "$input" "$out/pr.png" "$out/pi.exr" \
    2>&1 >/dev/null | tail -1
done
