#!/usr/bin/env bash
# Builds the sanitizer configuration in build-asan/: clang, AddressSanitizer + UndefinedBehaviorSanitizer
# on every target, libFuzzer coverage on the libraries. One build serves the sanitizer test suite
# (scripts/test.sh) and the fuzzers (scripts/fuzz.sh). Benchmarks are not built.
# -O1 and line tables only: fast enough to run, cheap to compile, readable stack traces.
set -euo pipefail
cd "$(dirname "$0")/.."
launcher=()
if [ -n "${CCACHE_DIR:-}" ] && command -v ccache > /dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
if [ ! -f build-asan/CMakeCache.txt ]; then
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
    -DSLAMVDB_SANITIZE=address,undefined -DSLAMVDB_FUZZ=ON "${launcher[@]}"
fi
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(slamvdb_tests slamvdb_cli fuzzers)
cmake --build build-asan -j"$(nproc)" --target "${targets[@]}"
