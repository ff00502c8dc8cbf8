#!/usr/bin/env bash
# Builds the sanitizer configuration in build-asan/: clang, AddressSanitizer + UndefinedBehaviorSanitizer
# on every target, libFuzzer coverage on the libraries. One build serves the sanitizer test suite
# (scripts/test.sh) and the fuzzers (scripts/fuzz.sh). Benchmarks are not built.
# -O1 and line tables only: fast enough to run, cheap to compile, readable stack traces.
# Without the TorchScript backend and query training (libtorch is not instrumented and its headers
# would triple the build) and without the Python module (CPython would need the ASan runtime
# preloaded): those run in the Release suite.
set -euo pipefail
cd "$(dirname "$0")/.."
launcher=()
if [ -n "${CCACHE_DIR:-}" ] && command -v ccache > /dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
if [ ! -f build-asan/CMakeCache.txt ]; then
  cmake -S . -B build-asan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
    -DSLAMVDB_SANITIZE=address,undefined -DSLAMVDB_FUZZ=ON \
    -DSLAMVDB_WITH_TORCH=OFF -DSLAMVDB_PYTHON_MODULE=OFF "${launcher[@]}"
fi
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(slamvdb_tests slamvdb_cli fuzzers)
cmake --build build-asan -j"$(nproc)" --target "${targets[@]}"
