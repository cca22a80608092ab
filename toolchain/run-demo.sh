#!/usr/bin/env bash
# The main job: builds tcpest (installing what is missing) and runs the demo
# on the built-in synthetic scene. Extra arguments go to `tcpest demo`.
set -euo pipefail
cd "$(dirname "$0")/.."
source toolchain/deps.sh
tcpest_install_deps "${TCPEST_BUILD_PACKAGES[@]}"
# Its own build folder: the test build's options stay as they are.
cmake -S . -B build/demo -DCMAKE_BUILD_TYPE=Release -DTCPEST_BUILD_TESTS=OFF -DTCPEST_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build build/demo --target tcpest -j"$(nproc)"
exec ./build/demo/firmware_like/tcpest demo "$@"
