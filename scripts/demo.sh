#!/usr/bin/env bash
# The main job on built-in defaults: install + build, then `slamvdb demo`: generate the default
# SIMULATED drive, map it, train query vectors on its first half, classify the map, evaluate it on
# the second half (paper Table 6.1) beside the per-image baseline, and write the pictures.
# Everything lands in out/ (override with OUT=...).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
exec build/slamvdb demo "${OUT:-out}"
