#!/usr/bin/env bash
# tools/shader_stats on Mesa's RADV without a GPU (its null winsys, an RDNA2
# part): the pipelines compile for a GPU compiler, and their registers stay
# where docs/ht.md ("On a real GPU") records them: `mis` within 128 VGPRs
# (eight waves per SIMD), `ht-frontier` with spheres.json's six caps
# within 200 and without spilling to scratch.
# Usage: shader_stats_test.sh SHADER_STATS SHADER_DIR
set -uo pipefail
bin=$1
shaders=$2
icd=/usr/share/vulkan/icd.d/radeon_icd.x86_64.json
if [ ! -f "$icd" ]; then
  echo "SKIP: no RADV driver ($icd)"
  exit 77
fi
export VK_DRIVER_FILES=$icd VK_ICD_FILENAMES=$icd RADV_FORCE_FAMILY=navi21
failures=0

# stat JSON NAME: the value of one statistic.
stat() { grep -o "\"$2\": *[0-9]*" <<<"$1" | head -1 | grep -o '[0-9]*$'; }

# check LABEL SPV METHOD CAPS: prints the pipeline's statistics, sets $out.
check() {
  out=$("$bin" "$shaders/$2" --method "$3" --cap-slots "$4" 2>&1)
  if [ $? -ne 0 ] || [ -z "$(stat "$out" VGPRs)" ]; then
    echo "FAIL: $1: $out"
    failures=$((failures + 1))
    out=""
    return 1
  fi
  echo "$1: VGPRs $(stat "$out" VGPRs), spilled $(stat "$out" 'Spilled VGPRs'), scratch $(stat "$out" 'Scratch size'), waves $(stat "$out" 'Subgroups per SIMD')"
}

if check mis baselines.fp32.spv 4 6; then
  [ "$(stat "$out" VGPRs)" -le 128 ] || { echo "FAIL: mis needs more than 128 VGPRs"; failures=$((failures + 1)); }
fi
if check ht-frontier frontier.fp32.spv 14 6; then
  [ "$(stat "$out" 'Spilled VGPRs')" -eq 0 ] && [ "$(stat "$out" 'Scratch size')" -eq 0 ] ||
    { echo "FAIL: ht-frontier spills with six caps"; failures=$((failures + 1)); }
  [ "$(stat "$out" VGPRs)" -le 200 ] || { echo "FAIL: ht-frontier needs more than 200 VGPRs"; failures=$((failures + 1)); }
fi
six=$(stat "$out" VGPRs)
# The statistics follow the specialization: sixteen caps (the most a
# pipeline holds) take more registers than six.
if [ -n "$six" ] && check ht-frontier-16-caps frontier.fp32.spv 14 16; then
  [ "$(stat "$out" VGPRs)" -gt "$six" ] || { echo "FAIL: sixteen caps take no more registers than six"; failures=$((failures + 1)); }
fi
# A file that is not SPIR-V: a one-line error and a non-zero exit.
printf 'not spir-v' >"${TMPDIR:-/tmp}/shader_stats_bad.spv"
if "$bin" "${TMPDIR:-/tmp}/shader_stats_bad.spv" >/dev/null 2>"${TMPDIR:-/tmp}/shader_stats_err"; then
  echo "FAIL: a bad SPIR-V file was accepted"; failures=$((failures + 1))
elif [ "$(wc -l <"${TMPDIR:-/tmp}/shader_stats_err")" -ne 1 ]; then
  echo "FAIL: not one line: $(cat "${TMPDIR:-/tmp}/shader_stats_err")"; failures=$((failures + 1))
fi
rm -f "${TMPDIR:-/tmp}/shader_stats_bad.spv" "${TMPDIR:-/tmp}/shader_stats_err"
[ $failures -eq 0 ] && echo "shader_stats: all passed"
exit $((failures > 0))
