#!/usr/bin/env bash
# Installs + builds (Release), then runs every test (unit, integration, CLI) with CTest; then the
# same tests under ASan + UBSan (GCC, build-asan/), the map's concurrency tests under
# ThreadSanitizer (clang, build-tsan/), then every fuzz harness for 20 s (clang, build-fuzz/).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 900
scripts/test_asan.sh
scripts/test_tsan.sh
scripts/fuzz.sh 20
