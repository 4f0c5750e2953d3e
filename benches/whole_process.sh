#!/usr/bin/env bash
# Whole-process timing of `rgbn eval graphs/input_image.ron` against its peer
# (../shared/peers/peer_graph.py), alternated, N rounds. Each round runs rgbn at two threads,
# at one thread (RAYON_NUM_THREADS=1) and on one core (taskset -c 0), then the peer; a `sync`
# (not timed) before every run, so no run pays for the previous one's dirty pages being
# written back under it. One line per run, "who wall user sys peak-RSS-KB"; medians go to
# BENCHMARKS.md (`python3 benches/medians.py LOG` prints them).
#
#   benches/whole_process.sh N4K.png [ROUNDS] [PYTHON] [RGBN]
#
# N4K.png: a 3840×2160 16-bit normal map (benches/make_big_png.py); PYTHON: an interpreter
# with numpy, opencv-python and OpenEXR (default python3); RGBN: the binary (default
# target/release/rgbn). RGBN_HUGE_PAGES=0 and RGBN_KEEP_FREED=0 pass through to rgbn.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
input="$1"; rounds="${2:-5}"; py="${3:-python3}"
rgbn="${4:-$here/target/release/rgbn}"
peer="$here/../shared/peers/peer_graph.py"
out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
run() { local who=$1; shift; sync; /usr/bin/time -f "$who %e %U %S %M" "$@" 2>&1 >/dev/null | tail -1; }
eval_args=(eval "$here/graphs/input_image.ron" --input "image=$input" -o "relit=$out/r.png" -o "image=$out/i.exr")
for _ in $(seq "$rounds"); do
  run rgbn-t2 env RAYON_NUM_THREADS=2 "$rgbn" "${eval_args[@]}"
  run rgbn-t1 env RAYON_NUM_THREADS=1 "$rgbn" "${eval_args[@]}"
  run rgbn-core1 taskset -c 0 "$rgbn" "${eval_args[@]}"
  run peer "$py" "$peer" "$input" "$out/pr.png" "$out/pi.exr"
done
