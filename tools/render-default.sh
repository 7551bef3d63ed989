#!/usr/bin/env bash
# Builds htrender and renders the default scene to out/spheres.{exr,png,json}.
set -euo pipefail
cd "$(dirname "$0")/.."
tools/build.sh
mkdir -p out
build/htrender render --scene data/scenes/spheres.json --method ht-frontier --spp 64 \
  --out out/spheres.exr --stats out/spheres.json "$@"
