#!/usr/bin/env bash
# Builds htrender and runs every test, in three stages:
#   1. the normal build (${BUILD_DIR:-build}) and its ctest suite;
#   2. the same suite, nothing excluded, built with AddressSanitizer and
#      UndefinedBehaviorSanitizer (g++, RelWithDebInfo) in ${ASAN_BUILD_DIR:-build-asan};
#   3. the libFuzzer targets, built with clang in build-fuzz, for
#      ${FUZZ_SECONDS:-30} seconds each (tools/fuzz.sh).
# Extra arguments go to both ctest runs. Stops at the first stage that fails.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
log=$(mktemp)
trap 'rm -f "$log"' EXIT
summary=()

# run_ctest <name> <build dir> [ctest args...]: the suite, then one closing line.
run_ctest() {
  local name=$1 dir=$2
  shift 2
  local rc=0
  ctest --test-dir "$dir" --output-on-failure --parallel "$jobs" "$@" 2>&1 | tee "$log" || rc=$?
  local result
  result=$(grep -E "tests passed, [0-9]+ tests? failed out of [0-9]+" "$log" | tail -1)
  [ -n "$result" ] || result="no test result (ctest exit $rc)"
  echo "== $name: $result"
  summary+=("$name: $result")
  return $rc
}

t0=$SECONDS
echo "== 1/3 normal build and tests (${BUILD_DIR:-build})"
tools/build.sh
run_ctest "normal" "${BUILD_DIR:-build}" "$@"
t1=$SECONDS

echo "== 2/3 AddressSanitizer + UndefinedBehaviorSanitizer build and tests (${ASAN_BUILD_DIR:-build-asan})"
sanitize="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all"
BUILD_DIR=${ASAN_BUILD_DIR:-build-asan} BUILD_TYPE=RelWithDebInfo tools/build.sh \
  -DCMAKE_C_FLAGS="$sanitize" -DCMAKE_CXX_FLAGS="$sanitize" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined"
# Any report ends the process with a non-zero status; leaks are reported.
saved_asan=${ASAN_OPTIONS-} saved_ubsan=${UBSAN_OPTIONS-}
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:check_initialization_order=1:strict_string_checks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
run_ctest "asan+ubsan" "${ASAN_BUILD_DIR:-build-asan}" "$@"
export ASAN_OPTIONS=$saved_asan UBSAN_OPTIONS=$saved_ubsan
[ -n "$ASAN_OPTIONS" ] || unset ASAN_OPTIONS
[ -n "$UBSAN_OPTIONS" ] || unset UBSAN_OPTIONS
t2=$SECONDS

echo "== 3/3 fuzzing (build-fuzz, ${FUZZ_SECONDS:-30} s per target)"
tools/fuzz.sh | tee "$log"
summary+=("fuzz: $(grep -c "no finding" "$log") targets without a finding")
t3=$SECONDS

echo "== all tests passed in $((t3 - t0)) s (normal $((t1 - t0)) s, asan+ubsan $((t2 - t1)) s, fuzz $((t3 - t2)) s)"
for line in "${summary[@]}"; do echo "   $line"; done
