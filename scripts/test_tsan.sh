#!/usr/bin/env bash
# The map's concurrency tests (finished submaps and the global index read from several threads
# while the active submap is written, moved and merged) built and run under ThreadSanitizer in
# build-tsan/ (GCC, unity build as in scripts/build_asan.sh; only the map library and its tests are
# built).
set -euo pipefail
cd "$(dirname "$0")/.."
launcher=()
if [ -n "${CCACHE_DIR:-}" ] && command -v ccache > /dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
if [ ! -f build-tsan/CMakeCache.txt ]; then
  cmake -S . -B build-tsan -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_UNITY_BUILD=ON \
    -DSLAMVDB_SANITIZE=thread -DSLAMVDB_WITH_TORCH=OFF -DSLAMVDB_PYTHON_MODULE=OFF \
    -DSLAMVDB_WERROR="${SLAMVDB_WERROR:-OFF}" "${launcher[@]}" > /dev/null
elif [ -n "${SLAMVDB_WERROR:-}" ]; then
  cmake build-tsan -DSLAMVDB_WERROR="$SLAMVDB_WERROR" > /dev/null  # a tree configured before: as asked now
fi
cmake --build build-tsan -j"$(nproc)" --target slamvdb_concurrency_tests
TSAN_OPTIONS=${TSAN_OPTIONS:-halt_on_error=1 exitcode=66 second_deadlock_stack=1} build-tsan/slamvdb_concurrency_tests
