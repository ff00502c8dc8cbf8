#!/usr/bin/env bash
# Installs + builds (Release), then runs every test (unit, integration, CLI, Python) with CTest, then
# the map's concurrency tests under ThreadSanitizer (GCC, build-tsan/). CI runs exactly this.
# Also available, not yet part of CI (see README, "Sanitizers"): scripts/test_asan.sh (the suite
# under ASan + UBSan) and scripts/fuzz.sh (every fuzz harness, 20 s each).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 900
scripts/test_tsan.sh
