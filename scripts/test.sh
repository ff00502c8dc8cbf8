#!/usr/bin/env bash
# Installs + builds (Release), then runs every test (unit, integration, CLI) with CTest.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 900
