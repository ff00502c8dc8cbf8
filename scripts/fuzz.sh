#!/usr/bin/env bash
# Runs the libFuzzer harnesses of fuzz/ (one per reader) under ASan + UBSan, each for SECONDS
# (default 20, what CI runs), starting from seed corpora written by fuzz_make_seeds.
#   scripts/fuzz.sh                    # every harness, 20 s each (CI)
#   scripts/fuzz.sh 3600 npy image     # long runs of some harnesses (names: build-fuzz/fuzz_<name>)
#   FUZZ_PARALLEL=1 scripts/fuzz.sh    # one harness at a time (default: one per core)
# The corpus of each harness grows in build-fuzz/fuzz/corpus/<name>/ across runs; a finding is written
# to build-fuzz/fuzz/artifacts/<name>/ (crash-*, timeout-*, oom-*, leak-*) and fails the run; replay
# it with build-fuzz/fuzz_<name> FILE.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-20}
[ $# -gt 0 ] && shift
FUZZ=1 scripts/build_asan.sh > /dev/null
bin=build-fuzz        # the harness executables
out=build-fuzz/fuzz   # seeds, corpora, artifacts and logs
mkdir -p "$out"
"$bin/fuzz_make_seeds" "$out/seeds" > /dev/null
harnesses=("$@")
if [ ${#harnesses[@]} -eq 0 ]; then
  for f in "$bin"/fuzz_*; do
    [ -x "$f" ] && [ -f "$f" ] || continue
    name=${f##*/fuzz_}
    [ "$name" = make_seeds ] || harnesses+=("$name")
  done
fi
# intercept_tls_get_addr=0: see scripts/test_asan.sh (LeakSanitizer's tracer crash with dlopen'd
# libraries' dynamic TLS, in clang 14's runtime too; the `image` harness loads the codecs plugin).
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:symbolize=1:intercept_tls_get_addr=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}

run_one() {
  local name=$1 seconds=$2 out=build-fuzz/fuzz
  mkdir -p "$out/corpus/$name" "$out/artifacts/$name" "$out/seeds/$name"
  # -timeout: an input taking 10 s is a hang; -rss_limit_mb: 2 GB is an out-of-memory finding.
  if "build-fuzz/fuzz_$name" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
      -artifact_prefix="$out/artifacts/$name/" "$out/corpus/$name" "$out/seeds/$name" > "$out/$name.log" 2>&1; then
    local execs
    execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$out/$name.log")
    printf 'fuzz %-16s ok    %6s s %10s executions, corpus %s\n' "$name" "$seconds" "$execs" \
      "$(ls "$out/corpus/$name" | wc -l)"
  else
    printf 'fuzz %-16s FAILED, see %s:\n' "$name" "$out/$name.log"
    grep -E "ERROR|SUMMARY|runtime error|Test unit written|uncaught|terminate" "$out/$name.log" | head -20
    return 1
  fi
}
export -f run_one
printf '%s\n' "${harnesses[@]}" |
  xargs -P "${FUZZ_PARALLEL:-$(nproc)}" -I{} bash -c "run_one {} $seconds"
