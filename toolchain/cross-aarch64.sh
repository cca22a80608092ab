#!/usr/bin/env bash
# Cross-compiles the libraries and tcpest for aarch64-linux-gnu with Debian's
# g++-aarch64-linux-gnu. libjpeg-turbo for arm64 comes from Debian multiarch.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! dpkg --print-foreign-architectures | grep -qx arm64; then
  dpkg --add-architecture arm64
  apt-get update -qq
fi
source toolchain/deps.sh
tcpest_install_deps g++-aarch64-linux-gnu libjpeg62-turbo-dev:arm64 libturbojpeg0-dev:arm64
cmake --preset aarch64 >/dev/null
cmake --build build/aarch64 -j"$(nproc)" --target tcpest
file build/aarch64/firmware_like/tcpest 2>/dev/null || ls -l build/aarch64/firmware_like/tcpest
