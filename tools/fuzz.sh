#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz/) with clang, AddressSanitizer and
# UndefinedBehaviorSanitizer into ${FUZZ_BUILD_DIR:-build-fuzz}, then runs
# fuzz_exr, fuzz_hdr and fuzz_scene side by side for ${FUZZ_SECONDS:-30} seconds each,
# starting from the seed corpora in tests/corpus/. New corpus entries stay in
# the build directory; an input that crashes is saved under
# <build>/findings/ and printed, and the script fails.
#
# To keep a finding as a regression test, copy it into tests/corpus/<target>/:
# the fuzz_corpus_* tests replay that corpus in every build.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/install-deps.sh
build=${FUZZ_BUILD_DIR:-build-fuzz}
seconds=${FUZZ_SECONDS:-30}
sanitize="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer"

CC=clang-14 CXX=clang++-14 cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DHT_FUZZ=ON \
  -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  -DCMAKE_C_FLAGS="$sanitize -fsanitize=fuzzer-no-link" \
  -DCMAKE_CXX_FLAGS="$sanitize -fsanitize=fuzzer-no-link" >/dev/null
cmake --build "$build" --parallel "$(nproc)" --target fuzz_exr fuzz_hdr fuzz_scene

# Leaks are checked by libFuzzer itself; OpenEXR's and oneTBB's one-time
# allocations stay reachable and are not reported.
export ASAN_OPTIONS=${ASAN_OPTIONS:-abort_on_error=0:detect_leaks=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
mkdir -p "$build/findings"
pids=()
targets=(exr hdr scene)
for target in "${targets[@]}"; do
  mkdir -p "$build/corpus/$target"
  # -max_len: seeds are below 2 KB, 64 KB leaves room for several chunks.
  # -rss_limit_mb: a header may not make the reader allocate more than this.
  "$build/fuzz_$target" "$build/corpus/$target" "tests/corpus/$target" \
    -dict="tests/fuzz/$target.dict" -max_total_time="$seconds" -timeout=20 -rss_limit_mb=2048 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$build/findings/$target-" \
    >"$build/fuzz_$target.log" 2>&1 &
  pids+=($!)
done
status=0
for i in "${!targets[@]}"; do
  target=${targets[$i]}
  if wait "${pids[$i]}"; then
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$build/fuzz_$target.log" | grep -o '[0-9]*$' || true)
    echo "fuzz_$target: no finding in ${seconds} s (${runs:-?} inputs; corpus $(ls "$build/corpus/$target" | wc -l) files)"
  else
    status=1
    echo "fuzz_$target: FINDING (log: $build/fuzz_$target.log)"
    grep -E "^(==[0-9]+==ERROR|SUMMARY|.*runtime error|artifact_prefix|Test unit written)" "$build/fuzz_$target.log" |
      head -20 || tail -40 "$build/fuzz_$target.log"
  fi
done
exit $status
