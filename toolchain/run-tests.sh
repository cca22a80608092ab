#!/usr/bin/env bash
# Every test and check of tcpest, as CI runs it: installs what is missing,
# builds (release with gcc; ASan + UBSan with clang; the fuzz targets;
# aarch64 cross), runs the unit and integration tests, the static
# analysers, the MISRA check (docs/coding-rules.md), the requirements trace,
# the coverage floor of the core units (toolchain/coverage.sh),
# a short fuzzing run (fuzz/), and the vcan tests (on the host or in a
# guest: tests/vcan/README.md), and a short soak of the loop. Each step
# prints its duration. `--quick` runs only the release build, its soak and
# its tests.
set -euo pipefail
cd "$(dirname "$0")/.."
source toolchain/deps.sh
tcpest_install_deps "${TCPEST_BUILD_PACKAGES[@]}" "${TCPEST_TEST_PACKAGES[@]}"
jobs="$(nproc)"
quick=0
[ "${1:-}" = "--quick" ] && quick=1

start_s="$(date +%s)"
step_s="$start_s"
step_name=""
step_done() {
  local now
  now="$(date +%s)"
  if [ -n "$step_name" ]; then
    printf '=== %s: %d s (total %d min) ===\n' "$step_name" "$((now - step_s))" "$(((now - start_s) / 60))"
  fi
  step_s="$now"
}
step() { step_done; step_name="$*"; printf '\n=== %s ===\n' "$*"; }
trap 'step_done' EXIT

step "release build (gcc)"
cmake --preset default >/dev/null
cmake --build build/default -j"$jobs"

# The loop over 20,000 cycles (about 70 s on 2 shared cores): no heap
# allocation, no heap growth, no drift of the cycle time, the same payloads
# on every pass over the replayed frames; exit 1 when a check fails
# (docs/loop.md, "Soak"; the long run is `tcpest bench --soak 1000000`).
step "soak (tcpest bench --soak 20000)"
build/default/firmware_like/tcpest bench --soak 20000

if [ "$quick" -eq 0 ]; then
  step "install, a project built against it, the Debian package"
  toolchain/check-install.sh build/default
  toolchain/check-package.sh build/default

  step "static analysis"
  toolchain/lint.sh build/default

  step "MISRA C:2012 addon (cppcheck), counts against toolchain/misra-baseline.txt"
  toolchain/misra.sh

  step "requirements trace (docs/requirements.md, the tests' Verifies markers, docs/trace.md)"
  python3 toolchain/trace.py --check-matrix docs/trace.md

  # One clang build for two checks: clang's warnings (-Werror) and the tests
  # under ASan + UBSan. The fuzz targets build apart: libFuzzer's comparison
  # hooks would make these tests ten times slower.
  step "sanitizer build (clang, ASan + UBSan) and its tests"
  cmake --preset asan >/dev/null
  cmake --build build/asan -j"$jobs"
  ctest --preset asan -j"$jobs"

  step "coverage of the core units by their tests (gcovr), floor 90 % lines, 75 % branches"
  toolchain/coverage.sh

  step "fuzz targets (libFuzzer, ASan + UBSan), 30 s each over their seed corpora"
  toolchain/fuzz.sh 30

  step "aarch64 cross build, its tests under qemu-user, the same bits as the host's"
  toolchain/cross-aarch64.sh --test

  step "vcan tests (SocketCAN against the kernel's vcan driver)"
  ctest --test-dir build/default -L vcan --output-on-failure
fi

step "tests (release)"
ctest --preset default -j"$jobs"
