#!/usr/bin/env bash
# Every test and check of tcpest, as CI runs it: installs what is missing,
# builds (release, sanitizers, clang, aarch64 cross), runs the unit and
# integration tests, the static analysers, the requirements trace, a short
# fuzzing run (fuzz/), and the vcan tests (on the host or in a guest:
# tests/vcan/README.md). `--quick`
# runs only the release build and its tests.
set -euo pipefail
cd "$(dirname "$0")/.."
source toolchain/deps.sh
tcpest_install_deps "${TCPEST_BUILD_PACKAGES[@]}" "${TCPEST_TEST_PACKAGES[@]}"
jobs="$(nproc)"
quick=0
[ "${1:-}" = "--quick" ] && quick=1

step() { printf '\n=== %s ===\n' "$*"; }

step "release build (gcc)"
cmake --preset default >/dev/null
cmake --build build/default -j"$jobs"

if [ "$quick" -eq 0 ]; then
  step "install, a project built against it, the Debian package"
  toolchain/check-install.sh build/default
  toolchain/check-package.sh build/default

  step "static analysis"
  toolchain/lint.sh build/default

  step "requirements trace (docs/requirements.md, the tests' Verifies markers, docs/trace.md)"
  python3 toolchain/trace.py --check-matrix docs/trace.md

  step "sanitizer build (ASan + UBSan) and its tests"
  cmake --preset asan >/dev/null
  cmake --build build/asan -j"$jobs"
  ctest --preset asan -j"$jobs"

  step "clang build"
  cmake --preset clang >/dev/null
  cmake --build build/clang -j"$jobs"

  step "fuzz targets (libFuzzer, ASan + UBSan), 30 s each over their seed corpora"
  toolchain/fuzz.sh 30

  step "aarch64 cross build, its tests under qemu-user, the same bits as the host's"
  toolchain/cross-aarch64.sh --test

  step "vcan tests (SocketCAN against the kernel's vcan driver)"
  ctest --test-dir build/default -L vcan --output-on-failure
fi

step "tests (release)"
ctest --preset default -j"$jobs"
