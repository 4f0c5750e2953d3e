#!/usr/bin/env bash
# `--region` of 1/16 of a store (issue 52): chunks read against the chunks that cover the
# region grown by the graph's halo, two ways: rgbn's own counter (`--stats`: "zarr chunks
# read") and the chunk files the process opened (`strace -f -e openat`, paths under the
# store's level folders, metadata and folder listings excluded). Regions: the interior quarter-of-a-quarter
# (N/4, N/4, N/4, N/4) and the corner one (0, 0, N/4, N/4). For a halo h with 0 < h < chunk
# the covering chunks are (N/4 / chunk + 2)² inside and (N/4 / chunk + 1)² at the corner.
#
#   benches/zarr_region_chunks.sh STORE.zarr [RGBN]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
store="$1"; rgbn="${2:-$here/target/release/rgbn}"
out="$(mktemp -d)"; trap 'rm -rf "$out"' EXIT
n=$(python3 -c "import json,sys; a=json.load(open(sys.argv[1]+'/0/zarr.json')); print(a['shape'][2], a['shape'][1], a['chunk_grid']['configuration']['chunk_shape'][2])" "$store")
read -r w h chunk <<<"$n"
q=$((w / 4)); qh=$((h / 4))
for r in "$q,$qh,$q,$qh" "0,0,$q,$qh"; do
  strace -f -qq -e trace=openat -o "$out/trace" "$rgbn" eval "$here/graphs/input_image.ron" \
    --input "image=$store" --region "$r" --stats -o "image=$out/part.exr" >"$out/stdout"
  counter=$(grep -o 'zarr chunks read: [0-9]*' "$out/stdout" | grep -o '[0-9]*$')
  opened=$(grep -F "$store/" "$out/trace" | grep -v -e 'zarr.json"' -e '\.zarray"' -e '\.zattrs"' -e 'ENOENT' -e 'O_DIRECTORY' | grep -c 'O_RDONLY' || true)
  levels=$(grep -F "$store/" "$out/trace" | grep -v -e 'zarr.json"' -e 'ENOENT' -e 'O_DIRECTORY' | grep -o "$store/[0-9]*/" | sort | uniq -c | tr '\n' ' ')
  x=${r%%,*}
  if [[ "$x" == 0 ]]; then cover=$(( (q / chunk + 1) * (qh / chunk + 1) )); else cover=$(( (q / chunk + 2) * (qh / chunk + 2) )); fi
  echo "region $r of ${w}x${h}, chunk $chunk: counter $counter, chunk files opened $opened (by level: $levels), covering region+halo $cover, ratio $(python3 -c "print(round($counter/$cover, 3), round($opened/$cover, 3))")"
done
