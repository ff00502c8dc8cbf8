#!/usr/bin/env bash
# The whole test suite (unit, integration, CLI) built with GCC under AddressSanitizer +
# UndefinedBehaviorSanitizer in build-asan/ (scripts/build_asan.sh). Any report (a memory error,
# undefined behaviour, a leak) aborts the process that triggered it, so the run fails.
#   scripts/test_asan.sh              the suite in gtest shards, one running per core (CI)
#   scripts/test_asan.sh -R REGEX     through CTest instead, one process per test (to replay one)
# The suite runs as a few gtest shards, not one process per test as under CTest: a suite's
# SetUpTestSuite (MappingPipelineTest synthesises a sequence, ImageBaselineTest maps one) then runs
# once per shard instead of once per test, and under ASan that set-up was most of the suite's time;
# the suites with the heaviest set-ups run whole, as jobs of their own, so theirs runs once. The Release suite (scripts/test.sh) keeps one process per test.
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
speed_checks="ClipTokenizer.ConstructionIsFast:SimulatedEncoders.EncodesAFullSizeFrameQuickly"
# Suites whose set-up (SetUpTestSuite, or inputs made once on first use) is heavy under ASan run
# whole, each as one job, instead of in every shard that draws one of their tests: gtest shards
# deal tests out one by one, so the set-up ran once per shard. Measured with the sanitizer scale on
# this 2-core machine (`--gtest_filter` of one test, wall time minus the test's own time):
# HonestAccuracyTest ~146 s (was paid in 4 shards), MappingPipelineTest ~52 s (6 shards),
# ImageBaselineTest ~13 s (2 shards), RecordingCommands' recordings ~40 s (on first use, 6 shards).
whole_suites=${ASAN_WHOLE_SUITES-"HonestAccuracyTest MappingPipelineTest RecordingCommands ImageBaselineTest"}
if [ -n "${GTEST_FILTER:-}" ]; then whole_suites=""; fi  # a filter of one's own: plain shards
shard_filter=${GTEST_FILTER:-"-$speed_checks$(for s in $whole_suites; do printf ':%s.*' "$s"; done)"}
# Three shards per core, taken by one worker per core as the previous one ends: with one shard per
# core the shard that drew the heaviest tests ran 709 s while the other was done at 447 s.
shards=${ASAN_SHARDS:-$((3 * $(nproc)))}
logs=build-asan/asan-logs
rm -rf $logs
mkdir -p $logs
# One job: a shard (a number) or a whole suite (its name).
run_asan_job() {
  local job=$1 shards=$2 logs=$3 shard_filter=$4 speed_checks=$5 log
  log=$logs/shard-$job.log
  if [[ $job =~ ^[0-9]+$ ]]; then
    GTEST_FILTER=$shard_filter GTEST_TOTAL_SHARDS=$shards GTEST_SHARD_INDEX=$job timeout 2400 \
      build-asan/slamvdb_tests > "$log" 2>&1  # each test's time is in the log
  else
    GTEST_FILTER="$job.*-$speed_checks" timeout 2400 build-asan/slamvdb_tests > "$log" 2>&1
  fi
  if [ $? -eq 0 ]; then
    echo "asan $job: $(grep -E '^\[  PASSED  \]' "$log")"
  else
    echo "asan $job FAILED ($log):"
    grep -E '^\[  FAILED  \]|ERROR: AddressSanitizer|ERROR: LeakSanitizer|runtime error|SUMMARY' "$log" | head -40
    tail -n 60 "$log"
    return 1
  fi
}
export -f run_asan_job
status=0
# The whole suites first (the longest jobs), then the shards.
{ for s in $whole_suites; do echo "$s"; done; seq 0 $((shards - 1)); } |
  xargs -P "$(nproc)" -I{} bash -c "run_asan_job {} $shards $logs '$shard_filter' '$speed_checks'" || status=1
# The two tests outside gtest (the map core alone, and what it links).
ctest --test-dir build-asan --output-on-failure -R '^MapCore\.' || status=1
exit $status
