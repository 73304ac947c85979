#!/usr/bin/env bash
# Seed corpus of the fuzz targets: the small committed text seeds (fuzz/corpus/<target>/)
# plus binary seeds made by our own writers, so that nothing large is committed: a pipeline
# of a few seconds (fuzz/corpus/run_config/tiny.toml) gives the HDF5 files of every reader,
# its terrain converted to PNG, TIFF and .asc gives the image and grid seeds, and its scene's
# CSV and PDB plant lists the text ones.
#   usage: fuzz/make_seeds.sh ECO_BINARY OUT_DIR   (run from anywhere)
set -euo pipefail
eco=$(realpath "$1")
out=$(realpath -m "$2")
root=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/eco-fuzz-seeds-XXXXXX")
trap 'rm -rf "$work"' EXIT

targets=(asc image biome_toml run_config csv biome_db sim_file canopy_file scene)
for t in "${targets[@]}"; do
  mkdir -p "$out/$t"
  if [ -d "$root/fuzz/corpus/$t" ]; then cp "$root/fuzz/corpus/$t"/* "$out/$t/"; fi
done
cp "$root/biomes/sonoma.toml" "$out/biome_toml/"
cp "$root/configs/demo.toml" "$out/run_config/"

# The pipeline runs from the repository root (tiny.toml names configs/ relative to itself).
# The same bytes on every run (no provenance; its folder named relative to the root, as the
# files record it), so that the fuzz runs of tools/sanitize.sh, whose libFuzzer seed is
# fixed, start from the same seeds.
run_rel="$(realpath -m --relative-to="$root" "$out").pipeline"
rm -rf "${root:?}/$run_rel"
(cd "$root" && "$eco" --no-provenance --threads 2 run fuzz/corpus/run_config/tiny.toml --out-dir "$run_rel" > "$work/run.log" 2>&1) || {
  cat "$work/run.log" >&2
  echo "make_seeds: the seed pipeline failed" >&2
  exit 1
}
r="$root/$run_rel"
"$eco" --no-provenance terrain generate --width 24 --height 16 --cell-size 2 --seed 5 --out "$work/small.h5" > /dev/null
"$eco" --no-provenance terrain convert "$work/small.h5" "$out/image/terrain16.png" > /dev/null
"$eco" --no-provenance terrain convert "$work/small.h5" "$out/image/terrain.tif" > /dev/null
"$eco" --no-provenance terrain convert "$work/small.h5" "$out/asc/terrain.asc" > /dev/null
cp "$r/biome-db.h5" "$out/biome_db/"
cp "$r/simulation.h5" "$out/sim_file/"
cp "$r/canopy.h5" "$out/canopy_file/"
cp "$r/scene.h5" "$out/scene/"
# The text plant lists, cut to a few KB.
for f in "$r"/*.csv; do head -c 3000 "$f" | sed '$d' > "$out/csv/$(basename "$f")"; done
rm -rf "${root:?}/$run_rel"
du -sh "$out"/* | sed 's/^/make_seeds: /'
