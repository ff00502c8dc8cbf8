#!/usr/bin/env bash
# Builds a sanitizer configuration: AddressSanitizer + UndefinedBehaviorSanitizer on every target.
#   scripts/build_asan.sh [targets]         build-asan/ with GCC: the test suite (scripts/test_asan.sh)
#   FUZZ=1 scripts/build_asan.sh [targets]  build-fuzz/ with clang and libFuzzer coverage (scripts/fuzz.sh)
# Two trees because Debian's Abseil is built with GCC: under clang's ASan the test suite crashed
# in the destructor of a class holding an absl::flat_hash_map (a corrupted neighbouring member),
# while GCC's ASan runs the same tests clean; libFuzzer exists only in clang, and
# the fuzzers build only the libraries, not the tests. Benchmarks are built in neither.
# -O1 and line tables only: fast enough to run, cheap to compile, readable stack traces.
# The test sources stay at -O1 too. At -O0 a test unity batch compiled in 23 s instead of 41 s
# (user time), but the inline and template code (Eigen) they instantiate is then what the linker
# keeps for the library's calls too: LidarOdometry.TracksShortLoopsOfOtherSeeds took 55 s instead
# of 34 s, a loss in the ASan tests larger than the gain in the build. Without UBSan on the tests
# (also 23 s) the library's calls into that code would lose UBSan's checks.
# Unity builds (CMake merges up to 16 sources of a target into one translation unit): Eigen,
# OpenCV, gtest, fmt and the project's headers are parsed once per batch instead of once per file,
# which is most of a sanitizer build's time (see README, "Sanitizers", for the measurements).
# Without the TorchScript backend and query training (libtorch is not instrumented and its headers
# would triple the build) and without the Python module (CPython would need the ASan runtime
# preloaded): those run in the Release suite.
set -euo pipefail
cd "$(dirname "$0")/.."
launcher=()
if [ -n "${CCACHE_DIR:-}" ] && command -v ccache > /dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
if [ "${FUZZ:-0}" = 1 ]; then
  tree=build-fuzz
  config=(-DCMAKE_CXX_COMPILER=clang++ -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" -DSLAMVDB_FUZZ=ON
          -DBUILD_TESTING=OFF)
  default_targets=(fuzzers)
else
  tree=build-asan
  config=(-DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1")  # the default compiler: GCC on Debian
  default_targets=(slamvdb_tests slamvdb_cli slamvdb_map_core_only)
fi
if [ ! -f $tree/CMakeCache.txt ]; then
  cmake -S . -B $tree -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "${config[@]}" \
    -DCMAKE_UNITY_BUILD=${SLAMVDB_UNITY:-ON} -DCMAKE_UNITY_BUILD_BATCH_SIZE=16 \
    -DSLAMVDB_SANITIZE=address,undefined -DSLAMVDB_WITH_TORCH=OFF -DSLAMVDB_PYTHON_MODULE=OFF \
    -DSLAMVDB_WERROR="${SLAMVDB_WERROR:-OFF}" "${launcher[@]}" > /dev/null
elif [ -n "${SLAMVDB_WERROR:-}" ]; then
  cmake $tree -DSLAMVDB_WERROR="$SLAMVDB_WERROR" > /dev/null  # a tree configured before: as asked now
fi
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=("${default_targets[@]}")
cmake --build $tree -j"$(nproc)" --target "${targets[@]}"
