#!/usr/bin/env bash
# The main job on built-in defaults: install + build, generate the default SIMULATED sequence,
# map it, and export pictures. Everything lands in out/ (override with OUT=...).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
OUT=${OUT:-out}
BIN=build/slamvdb
mkdir -p "$OUT"
[ -f "$OUT/sequence/synth.json" ] || "$BIN" synth "$OUT/sequence" --force
"$BIN" map "$OUT/sequence" -o "$OUT/map.svdb"
"$BIN" info "$OUT/map.svdb"
"$BIN" export "$OUT/map.svdb" --ply "$OUT/map.ply" --png "$OUT/map.png"
echo "done: $OUT/map.svdb, $OUT/map.ply, $OUT/map.png"
