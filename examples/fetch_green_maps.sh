#!/bin/sh
# Fetches the published normal maps of tests/data/green_convention_maps.tsv (third-party data,
# never committed) into DIR (default: target/green-maps), each from its repository at the pinned
# commit on raw.githubusercontent.com. Then: cargo run --release --example green_maps -- DIR
# (docs/green-convention.md). Files already present are kept.
set -eu
here=$(dirname "$0")
manifest="$here/../tests/data/green_convention_maps.tsv"
dir=${1:-"$here/../target/green-maps"}
mkdir -p "$dir"
grep -v '^#' "$manifest" | while IFS="$(printf '\t')" read -r file conv kind repo commit path reason; do
  [ -n "$file" ] || continue
  if [ -s "$dir/$file" ]; then continue; fi
  url="https://raw.githubusercontent.com/$repo/$commit/$(printf '%s' "$path" | sed 's/ /%20/g')"
  echo "fetching $file ($repo $path)"
  curl -fsSL --retry 2 -o "$dir/$file.part" "$url" && mv "$dir/$file.part" "$dir/$file"
done
echo "maps in $dir: $(ls "$dir" | wc -l)"
