#!/usr/bin/env bash
# Installs htrender's build and test dependencies from Debian 12 packages.
# Idempotent: does nothing when every package is already installed.
set -euo pipefail

packages=(
  build-essential cmake pkg-config ninja-build
  libvulkan-dev mesa-vulkan-drivers glslang-tools libvulkan-volk-dev
  vulkan-validationlayers vulkan-tools spirv-tools
  libglm-dev libfmt-dev libopenexr-dev nlohmann-json3-dev libcli11-dev libtbb-dev
  libgtest-dev libpng-dev libchealpix-dev libstb-dev
  clang-14 libclang-rt-14-dev
  python3-matplotlib python3-numpy
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0

SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
