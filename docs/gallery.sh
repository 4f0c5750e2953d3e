#!/usr/bin/env bash
# Regenerates the pictures of docs/gallery.md from graphs/paper/*.ron and prints each graph's
# per-node statistics (the F column gives the gallery's "F before / after").
# Run from the repository root:  bash docs/gallery.sh
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin rgbn
rgbn=target/release/rgbn
out=docs/gallery
mkdir -p "$out"
for g in graphs/paper/*.ron; do
    stem=$(basename "$g" .ron)
    args=()
    # Every output whose name ends in "picture" is written as STEM.NAME.png.
    for name in $(grep -o '"[a-z_]*picture": (node' "$g" | cut -d'"' -f2); do
        args+=(-o "$name=$out/$stem.$name.png")
    done
    echo "== $stem"
    "$rgbn" eval "$g" "${args[@]}" --stats
done
