#!/usr/bin/env bash
# The whole test suite (unit, integration, CLI) built with GCC under AddressSanitizer +
# UndefinedBehaviorSanitizer in build-asan/ (scripts/build_asan.sh). Any report (a memory error,
# undefined behaviour, a leak) aborts the process that triggered it, so the run fails.
#   scripts/test_asan.sh              the suite in gtest shards, one running per core (CI)
#   scripts/test_asan.sh -R REGEX     through CTest instead, one process per test (to replay one)
# The suite runs as a few gtest shards, not one process per test as under CTest: a suite's
# SetUpTestSuite (MappingPipelineTest synthesises a sequence, ImageBaselineTest maps one) then runs
# once per shard instead of once per test, and under ASan that set-up was most of the suite's time. The Release suite (scripts/test.sh) keeps one process per test.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build_asan.sh
# detect_stack_use_after_return stays at ASan's default (off): it doubled the suite's CPU time
# (measured on LoopClosingMapper.VerificationRejectsAWrongCandidate: 29 s -> 14.5 s); turn it on for
# a deeper local run with ASAN_OPTIONS=...:detect_stack_use_after_return=1.
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:strict_string_checks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
# The few tests that simulate and register long LiDAR drives take a shorter part of them
# (src/slamvdb/testing/test_scale.hpp); the Release suite runs them at full size.
export SLAMVDB_TEST_SCALE=${SLAMVDB_TEST_SCALE:-sanitizer}
if [ $# -gt 0 ]; then
  # Install.* installs and builds another project: a Release-suite check, not a sanitizer one.
  exec ctest --test-dir build-asan --output-on-failure -j"$(nproc)" --timeout 900 -E '^Install\.' "$@"
fi

# Pure speed checks, meaningless under -O1 instrumentation (their code runs under ASan in the other
# tests of the same suites; their time bounds are checked by the Release suite).
export GTEST_FILTER=${GTEST_FILTER:-"-ClipTokenizer.ConstructionIsFast:SimulatedEncoders.EncodesAFullSizeFrameQuickly"}
# Three shards per core, taken by one worker per core as the previous one ends: with one shard per
# core the shard that drew the heaviest tests ran 709 s while the other was done at 447 s.
shards=${ASAN_SHARDS:-$((3 * $(nproc)))}
logs=build-asan/asan-logs
rm -rf $logs
mkdir -p $logs
run_shard() {
  local i=$1 shards=$2 logs=$3
  if GTEST_TOTAL_SHARDS=$shards GTEST_SHARD_INDEX=$i timeout 2400 build-asan/slamvdb_tests \
      > $logs/shard-$i.log 2>&1; then  # each test's time is in the log
    echo "asan shard $((i + 1))/$shards: $(grep -E '^\[  PASSED  \]' $logs/shard-$i.log)"
  else
    echo "asan shard $((i + 1))/$shards FAILED ($logs/shard-$i.log):"
    grep -E '^\[  FAILED  \]|ERROR: AddressSanitizer|ERROR: LeakSanitizer|runtime error|SUMMARY' $logs/shard-$i.log | head -40
    tail -n 60 $logs/shard-$i.log
    return 1
  fi
}
export -f run_shard
status=0
seq 0 $((shards - 1)) | xargs -P "$(nproc)" -I{} bash -c "run_shard {} $shards $logs" || status=1
# The two tests outside gtest (the map core alone, and what it links).
ctest --test-dir build-asan --output-on-failure -R '^MapCore\.' || status=1
exit $status
