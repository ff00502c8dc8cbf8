#!/usr/bin/env bash
# The whole test suite (unit, integration, CLI) built with GCC under AddressSanitizer +
# UndefinedBehaviorSanitizer in build-asan/ (scripts/build_asan.sh). Any report (a memory error,
# undefined behaviour, a leak) aborts the test that triggered it, so the test fails.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/build_asan.sh
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}
# Install.* installs and builds another project: a Release-suite check, not a sanitizer one.
ctest --test-dir build-asan --output-on-failure -j"$(nproc)" --timeout 900 -E '^Install\.' "$@"
