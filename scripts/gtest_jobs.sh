#!/usr/bin/env bash
# Runs one gtest binary as parallel jobs, one per core: the suites with heavy set-ups whole (one job
# each, the longest first), then the rest in 3 shards per core, then the short whole suites. Used by
# the Release stage (scripts/test_release.sh) and the ASan stage (scripts/test_asan.sh).
#   scripts/gtest_jobs.sh BINARY LOGDIR NAME
# GTEST_FILTER: a filter of one's own (then plain shards, no whole suites); SKIP_TESTS: tests left out
# (a gtest filter without the leading '-'); WHOLE_SUITES, LAST_SUITES, SHARDS override the defaults below.
# Why not CTest's one process per test: a suite's SetUpTestSuite (HonestAccuracyTest maps a drive,
# MappingPipelineTest synthesises a sequence, RecordingCommands writes recordings on first use) then
# ran once per test; in shards it runs once per shard that draws one of the suite's tests (gtest deals
# tests out one by one), and for the suites below, whose set-up is heavy, once. Measured under ASan
# with the sanitizer scale on this 2-core machine (wall time of a one-test filter minus the test's own):
# HonestAccuracyTest ~146 s (was paid in 4 shards), MappingPipelineTest ~52 s (6 shards),
# ImageBaselineTest ~13 s (2 shards), RecordingCommands' recordings ~40 s (6 shards).
set -uo pipefail
binary=$1 logs=$2 name=$3
whole_suites=${WHOLE_SUITES-"HonestAccuracyTest MappingPipelineTest"}
# Whole suites queued after the shards: short jobs (ASan: 36 and 5 s; Release: 38 and 1 s) that
# fill the end, where a core waited for the other's last shard (55 s in the ASan run of
# 2026-11-27 08:00, when they ran first).
last_wanted=${LAST_SUITES-"RecordingCommands ImageBaselineTest"} last_suites=""
for s in $last_wanted; do
  [[ " $whole_suites " == *" $s "* ]] || last_suites+="$s "  # a suite named in both runs once
done
skip=${SKIP_TESTS:-}
if [ -n "${GTEST_FILTER:-}" ]; then whole_suites="" last_suites=""; fi
shard_filter=${GTEST_FILTER:-"-$skip$(for s in $whole_suites $last_suites; do printf ':%s.*' "$s"; done)"}
# Three shards per core, taken by one worker per core as the previous one ends: with one shard per
# core the shard that drew the heaviest tests ran 709 s under ASan while the other was done at 447 s.
shards=${SHARDS:-$((3 * $(nproc)))}
rm -rf "$logs"
mkdir -p "$logs"
# One job: a shard (a number) or a whole suite (its name). Each test's time is in the job's log.
run_job() {
  local job=$1 binary=$2 logs=$3 name=$4 shards=$5 shard_filter=$6 skip=$7 log status=0
  log=$logs/$job.log
  if [[ $job =~ ^[0-9]+$ ]]; then
    GTEST_FILTER=$shard_filter GTEST_TOTAL_SHARDS=$shards GTEST_SHARD_INDEX=$job timeout 2400 \
      "$binary" > "$log" 2>&1 || status=$?
  else
    GTEST_FILTER="$job.*${skip:+-$skip}" timeout 2400 "$binary" > "$log" 2>&1 || status=$?
  fi
  if [ $status -eq 0 ]; then
    echo "$name $job: $(grep -E '^\[  PASSED  \]' "$log")"
  else
    echo "$name $job FAILED (exit $status, $log):"
    grep -E '^\[  FAILED  \]|ERROR: AddressSanitizer|ERROR: LeakSanitizer|runtime error|SUMMARY' "$log" | head -40
    tail -n 60 "$log"
    return 1
  fi
}
export -f run_job
{ for s in $whole_suites; do echo "$s"; done; seq 0 $((shards - 1)); for s in $last_suites; do echo "$s"; done; } |
  xargs -P "$(nproc)" -I{} bash -c "run_job {} '$binary' '$logs' '$name' $shards '$shard_filter' '$skip'"
