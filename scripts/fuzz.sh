#!/usr/bin/env bash
# Builds the libFuzzer targets (CMake preset `fuzz`: clang, ASan + UBSan) and runs each one on its
# seed corpus for the given time (docs/fuzzing.md). One target at a time.
#
#   scripts/fuzz.sh [seconds-per-target] [target...]     default: 30 s, every target
#
# New interesting inputs go to build/fuzz/corpus/<target>/ (fuzz/corpus/ stays as committed);
# crashes, timeouts and out-of-memory inputs to build/fuzz/crashes/<target>/. Exits non-zero when
# any target found one. Needs clang and libFuzzer (Debian 12: clang, libclang-rt-14-dev).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-30}"
shift || true
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"

cmake --preset fuzz >/dev/null
cmake --build --preset fuzz

targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then
  for seeds in fuzz/corpus/*/; do targets+=("$(basename "$seeds")"); done
fi

# Reports are findings: stop at the first UBSan report; keep other libraries' known leaks out
# (fuzz/lsan.supp).
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$PWD/fuzz/lsan.supp}"

failed=()
for target in "${targets[@]}"; do
  binary="build/fuzz/fuzz/${target}_fuzzer"
  work="build/fuzz/corpus/${target}"
  crashes="build/fuzz/crashes/${target}"
  mkdir -p "$work" "$crashes"
  echo "== ${target}: ${seconds} s"
  if ! "$binary" "$work" "fuzz/corpus/${target}" -max_total_time="$seconds" -rss_limit_mb=2048 \
    -timeout=10 -print_final_stats=1 -artifact_prefix="${crashes}/" \
    >"build/fuzz/${target}.log" 2>&1; then
    failed+=("$target")
    echo "   FAILED: see build/fuzz/${target}.log and ${crashes}/"
  fi
  grep -E '^stat::(number_of_executed_units|peak_rss_mb)|^Done [0-9]+ runs' \
    "build/fuzz/${target}.log" | sed 's/^/   /' || true
done

if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzzing found problems in: ${failed[*]}" >&2
  exit 1
fi
echo "fuzzing: no crash in ${#targets[@]} targets"
