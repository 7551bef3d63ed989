#!/usr/bin/env bash
# Builds htrender and runs every test.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/build.sh
export MESA_SHADER_CACHE_DISABLE=true
ctest --test-dir "${BUILD_DIR:-build}" --output-on-failure --parallel "$(nproc)" "$@"
