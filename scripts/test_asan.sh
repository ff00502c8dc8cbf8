#!/usr/bin/env bash
# The whole test suite (unit, integration, CLI) built with GCC under AddressSanitizer +
# UndefinedBehaviorSanitizer in build-asan/ (scripts/build_asan.sh). Any report (a memory error,
# undefined behaviour, a leak) aborts the process that triggered it, so the run fails.
#   scripts/test_asan.sh              the suite in gtest shards, one running per core (CI)
#   scripts/test_asan.sh -R REGEX     through CTest instead, one process per test (to replay one)
# The suite runs as parallel gtest jobs (scripts/gtest_jobs.sh: heavy-set-up suites whole, the rest
# in shards), not one process per test as under CTest, so that a suite's set-up is not repeated.
set -euo pipefail
cd "$(dirname "$0")/.."
# OpenBLAS (Ceres' SuiteSparse links it) starts a worker thread in every process, which spins on
# sched_yield for a while even in runs that never call BLAS: on 2 cores, beside the other test job,
# in each of the ~600 CLI starts of the suite. Nothing here needs a parallel BLAS.
export OPENBLAS_NUM_THREADS=${OPENBLAS_NUM_THREADS:-1}
scripts/build_asan.sh
# detect_stack_use_after_return stays at ASan's default (off): it doubled the suite's CPU time
# (measured on LoopClosingMapper.VerificationRejectsAWrongCandidate: 29 s -> 14.5 s); turn it on for
# a deeper local run with ASAN_OPTIONS=...:detect_stack_use_after_return=1.
# intercept_tls_get_addr=0: GCC 12's sanitizer runtime (up to GCC 13 / LLVM 16) takes a dynamic TLS
# block that happens to start at the offset of a pre-2.25 glibc block header within its page for
# such a block, reads a start and length from before it, and LeakSanitizer's tracer then dies at
# exit ("Tracer caught signal 11", "LeakSanitizer has encountered a fatal error": a crash of the
# tool, no leak). The blocks are malloc'd, so it strikes by chance: since the image codecs are a
# plugin (dlopen of imgcodecs and the ~140 libraries it links, many with TLS), it hit the McapExport
# set-up's CLI run in 2 of the last 4 whole ASan runs here (google/sanitizers#1322, Mudlet#9809).
# What is lost: the dynamic TLS of dlopen'd libraries is not scanned for pointers (their static TLS
# and every thread's stack still are), which could only add a false leak report.
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:strict_string_checks=1:intercept_tls_get_addr=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
# Leaks inside third-party libraries' error paths only (the file says which and why).
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$PWD/scripts/lsan_suppressions.txt:print_suppressions=0}
# The few tests that simulate and register long LiDAR drives take a shorter part of them
# (src/slamvdb/testing/test_scale.hpp); the Release suite runs them at full size.
export SLAMVDB_TEST_SCALE=${SLAMVDB_TEST_SCALE:-sanitizer}
if [ $# -gt 0 ]; then
  # Install.* installs and builds another project: a Release-suite check, not a sanitizer one.
  exec ctest --test-dir build-asan --output-on-failure -j"$(nproc)" --timeout 900 -E '^Install\.' "$@"
fi

# Pure speed checks, meaningless under -O1 instrumentation (their code runs under ASan in the other
# tests of the same suites; their time bounds are checked by the Release suite).
status=0
# TwoDriveLookAlikes simulates and maps three 70-100 m drives (20 s of CPU in Release, about 150 s
# here); the consensus and refusals it checks run under ASan in AlignSessions.*.
# SessionRefinement aligns a 100 m pair and then redoes every submap's refinement on one thread
# (8-14 s in Release at load): the shared planes and parallel refinements it compares run under
# ASan in every AlignSessions.* alignment.
SKIP_TESTS="ClipTokenizer.ConstructionIsFast:SimulatedEncoders.EncodesAFullSizeFrameQuickly:TwoDriveLookAlikes.*:SessionRefinement.*" \
  scripts/gtest_jobs.sh build-asan/slamvdb_tests build-asan/asan-logs asan || status=1
# The two tests outside gtest (the map core alone, and what it links).
ctest --test-dir build-asan --output-on-failure -R '^MapCore\.' || status=1
exit $status
