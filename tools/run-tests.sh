#!/usr/bin/env bash
# Builds htrender and runs its tests.
#
#   tools/run-tests.sh          the normal build (${BUILD_DIR:-build}) and its
#                               ctest suite without the `slow` tier (a few minutes)
#   tools/run-tests.sh --full   everything, as CI runs it:
#     1. the normal build and its whole ctest suite, the slow tier included;
#     2. the same suite built with AddressSanitizer and UndefinedBehaviorSanitizer
#        (g++, RelWithDebInfo) in ${ASAN_BUILD_DIR:-build-asan};
#     3. the CPU/GPU equivalence tests built with clang in ${CLANG_BUILD_DIR:-build-clang};
#     4. the libFuzzer targets, built with clang in build-fuzz, for
#        ${FUZZ_SECONDS:-30} seconds each (tools/fuzz.sh).
# Other arguments go to every ctest run. Stops at the first stage that fails.
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

full=0
if [ "${1-}" = "--full" ]; then
  full=1
  shift
fi

t0=$SECONDS
if [ $full -eq 0 ]; then
  echo "== normal build and tests without the slow tier (${BUILD_DIR:-build})"
  tools/build.sh
  run_ctest "normal" "${BUILD_DIR:-build}" -LE slow "$@"
  echo "== tests passed in $((SECONDS - t0)) s; tools/run-tests.sh --full adds the slow tier, sanitizers, clang and fuzzing"
  exit 0
fi

echo "== 1/4 normal build and tests, slow tier included (${BUILD_DIR:-build})"
tools/build.sh
run_ctest "normal" "${BUILD_DIR:-build}" "$@"
t1=$SECONDS

echo "== 2/4 AddressSanitizer + UndefinedBehaviorSanitizer build and tests (${ASAN_BUILD_DIR:-build-asan})"
sanitize="-fsanitize=address,undefined -fno-omit-frame-pointer -fno-sanitize-recover=all"
BUILD_DIR=${ASAN_BUILD_DIR:-build-asan} BUILD_TYPE=RelWithDebInfo tools/build.sh \
  -DCMAKE_C_FLAGS="$sanitize" -DCMAKE_CXX_FLAGS="$sanitize" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined"
# Any report ends the process with a non-zero status; leaks are reported,
# but for the block the Vulkan driver keeps for good (tools/lsan.supp).
saved_asan=${ASAN_OPTIONS-} saved_ubsan=${UBSAN_OPTIONS-} saved_lsan=${LSAN_OPTIONS-}
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:check_initialization_order=1:strict_string_checks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$PWD/tools/lsan.supp:print_suppressions=0}
run_ctest "asan+ubsan" "${ASAN_BUILD_DIR:-build-asan}" -LE slow "$@"
export ASAN_OPTIONS=$saved_asan UBSAN_OPTIONS=$saved_ubsan LSAN_OPTIONS=$saved_lsan
[ -n "$ASAN_OPTIONS" ] || unset ASAN_OPTIONS
[ -n "$UBSAN_OPTIONS" ] || unset UBSAN_OPTIONS
[ -n "$LSAN_OPTIONS" ] || unset LSAN_OPTIONS
t2=$SECONDS

# The CPU reference must draw the same numbers whichever conforming compiler
# builds it: the GPU equivalence tests again, built with clang.
echo "== 3/4 clang build and the CPU/GPU equivalence tests (${CLANG_BUILD_DIR:-build-clang})"
BUILD_DIR=${CLANG_BUILD_DIR:-build-clang} tools/build.sh \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14
run_ctest "clang" "${CLANG_BUILD_DIR:-build-clang}" -R "Gpu(SameSeed|Ht|HighSpp)" -LE slow "$@"
t3=$SECONDS

echo "== 4/4 fuzzing (build-fuzz, ${FUZZ_SECONDS:-30} s per target)"
tools/fuzz.sh | tee "$log"
summary+=("fuzz: $(grep -c "no finding" "$log") targets without a finding")
t4=$SECONDS

echo "== all tests passed in $((t4 - t0)) s (normal $((t1 - t0)) s, asan+ubsan $((t2 - t1)) s, clang $((t3 - t2)) s, fuzz $((t4 - t3)) s)"
for line in "${summary[@]}"; do echo "   $line"; done
