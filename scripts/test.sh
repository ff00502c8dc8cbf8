#!/usr/bin/env bash
# Every check, one stage after the other; CI runs exactly this (.ci/run), from a clean clone:
#   setup          scripts/setup.sh: installs, builds in Release (build/, a unity build)
#   release tests  scripts/test_release.sh: every test (unit, integration, CLI, Python, viewer)
#   tsan           scripts/test_tsan.sh: the concurrency tests (map, streaming mapper) under TSan
#   asan build     scripts/build_asan.sh: the test suite under ASan + UBSan (GCC, build-asan/)
#   asan tests     scripts/test_asan.sh: that suite (any report fails the test)
#   fuzz build     FUZZ=1 scripts/build_asan.sh: the libFuzzer harnesses (clang, build-fuzz/)
#   fuzz runs      scripts/fuzz.sh: every harness for FUZZ_SECONDS (default 10) s
# SLAMVDB_SANITIZERS=0 leaves out the last four (the quick local check). Each stage's wall time is
# printed at the end, also when a stage fails (README, "Bad input, limits, sanitizers and fuzzing").
set -euo pipefail
cd "$(dirname "$0")/.."
# A warning in the project's code fails every build here (SLAMVDB_WERROR; README, "Warnings").
export SLAMVDB_WERROR=${SLAMVDB_WERROR:-ON}

stage_rows=()
stage() {
  local name=$1 start=$SECONDS status=0
  shift
  echo "=== $name: $*"
  "$@" || status=$?
  stage_rows+=("$(printf '%-14s %6d s  %s' "$name" $((SECONDS - start)) "$([ $status = 0 ] && echo ok || echo "FAILED ($status)")")")
  return $status
}
print_stage_times() {
  echo "=== stage times (wall)"
  printf '%s\n' "${stage_rows[@]}"
  printf '%-14s %6d s\n' total $SECONDS
}
trap print_stage_times EXIT

stage setup scripts/setup.sh
stage "release tests" scripts/test_release.sh
stage tsan scripts/test_tsan.sh
if [ "${SLAMVDB_SANITIZERS:-1}" = 1 ]; then
  stage "asan build" scripts/build_asan.sh
  stage "asan tests" scripts/test_asan.sh
  stage "fuzz build" env FUZZ=1 scripts/build_asan.sh
  stage "fuzz runs" scripts/fuzz.sh "${FUZZ_SECONDS:-10}"
fi
