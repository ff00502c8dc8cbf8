#!/usr/bin/env bash
# The Release suite (build/, made by scripts/setup.sh): the gtest binary as parallel gtest jobs
# (scripts/gtest_jobs.sh: suites with heavy set-ups whole, the rest in shards), and beside it the
# tests outside gtest (Python, install, map core alone) through CTest.
#   scripts/test_release.sh              everything (CI's "release tests" stage)
#   scripts/test_release.sh -R REGEX     through CTest instead, one process per test (to replay one)
# One process per test under CTest repeated each suite's set-up for every test: 476 s for this stage
# on the 2-core machine, against the jobs' time printed at the end of scripts/test.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
# OpenBLAS (Ceres' SuiteSparse links it) starts a worker thread in every process, which spins on
# sched_yield for a while even in runs that never call BLAS: on 2 cores, beside the other test job,
# in each of the ~600 CLI starts of the suite. Nothing here needs a parallel BLAS.
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}
if [ $# -gt 0 ]; then
  exec ctest --test-dir build --output-on-failure -j"$(nproc)" --timeout 900 "$@"
fi
status=0
ctest --test-dir build --output-on-failure --timeout 900 -LE '^gtest$' > build/ctest-other.log 2>&1 &
other=$!
scripts/gtest_jobs.sh build/slamvdb_tests build/test-logs release || status=1
if wait $other; then
  echo "release (outside gtest): $(grep -E 'tests passed' build/ctest-other.log)"
else
  echo "release (outside gtest) FAILED:"; cat build/ctest-other.log; status=1
fi
exit $status
