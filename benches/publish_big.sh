#!/usr/bin/env bash
# BENCHMARKS.md "Streaming publish": rgbn publish of a 16384² and a 4096² 16-bit PNG, alternated,
# whole process (/usr/bin/time: wall, user, sys, peak RSS), then the bytes written against the
# tile files alone.
#   benches/publish_big.sh RGBN_BINARY N16K.png N4K.png OUTDIR [RUNS]
# Inputs: python3 benches/make_big_png.py 16384 16384 n16k.png (and 4096 4096 n4k.png).
set -euo pipefail
bin=$1 big=$2 small=$3 out=$4 runs=${5:-5}
mkdir -p "$out"
uptime
for i in $(seq 1 "$runs"); do
  for which in big small; do
    input=${!which}
    /usr/bin/time -f "$which %e %U %S %M" "$bin" publish "$input" -o "$out/web-$which" \
      >/dev/null 2>>"$out/times.txt"
    tail -n 1 "$out/times.txt"
  done
done
uptime
for which in big small; do
  total=$(find "$out/web-$which" -type f -printf '%s\n' | awk '{s += $1} END {print s}')
  tiles=$(find "$out/web-$which" -path '*_files/*' -name '*.png' -printf '%s\n' | awk '{s += $1} END {print s}')
  n=$(find "$out/web-$which" -path '*_files/*' -name '*.png' | wc -l)
  echo "$which: $n tile files, tiles $tiles bytes, all files $total bytes, ratio $(echo "$total / $tiles" | bc -l)"
done
# Medians per input: wall, user, sys, peak RSS (KiB).
for which in big small; do
  grep "^$which " "$out/times.txt" | awk '{print $2, $3, $4, $5}' | sort -n | awk -v w="$which" '
    {a[NR] = $0} END {print w " median (wall user sys rss_kib): " a[int((NR + 1) / 2)]}'
done
