#!/usr/bin/env bash
# Cross-compiles the libraries and tcpest for aarch64-linux-gnu with Debian's
# g++-aarch64-linux-gnu. libjpeg-turbo for arm64 comes from Debian multiarch.
#
# --test (x86-64 hosts): also runs the ARM64 build under qemu-user, to show
# that it computes what the host build computes (docs/architecture.md,
# "Reproducible arithmetic"):
#   1. the unit tests of common (dmath's pinned checksums), solver, can_iface
#      and the hal's CAN, clock and camera units, built for aarch64;
#   2. 12 frames of the hard set rendered by both builds: the same bytes;
#   3. those frames estimated by both builds (tcpest estimate --json, the
#      temporal priors chaining them): the same output but the timings.
# The host's release build (build/default) must exist for 2 and 3.
# --test all: every test of the ARM64 build but the vcan ones; not in CI
# (on two cores, 380 tests take about 25 minutes under emulation, and the
# demo's and the bench's command tests far longer).
set -euo pipefail
cd "$(dirname "$0")/.."
if ! dpkg --print-foreign-architectures | grep -qx arm64; then
  dpkg --add-architecture arm64
  apt-get update -qq
fi
source toolchain/deps.sh
tcpest_install_deps g++-aarch64-linux-gnu libjpeg62-turbo-dev:arm64 libturbojpeg0-dev:arm64
if [ "${1:-}" != "--test" ]; then
  cmake --preset aarch64 >/dev/null
  cmake --build build/aarch64 -j"$(nproc)" --target tcpest
  file build/aarch64/firmware_like/tcpest 2>/dev/null || ls -l build/aarch64/firmware_like/tcpest
  exit 0
fi
if [ "$(uname -m)" != "x86_64" ]; then
  echo "cross-aarch64.sh --test: an x86-64 host is needed to compare the two builds; skipped"
  exit 0
fi
tcpest_install_deps qemu-user libgtest-dev:arm64
# One build (preset aarch64-test: the libraries once, tcpest and the tests).
build=build/aarch64-test
host_tcpest=build/default/firmware_like/tcpest
arm_tcpest=(qemu-aarch64 -L /usr/aarch64-linux-gnu "$build/firmware_like/tcpest")
cmake --preset aarch64-test >/dev/null
# Left out under emulation: the death test re-executes its ARM64 binary
# (that needs binfmt_misc, which a container may not have); the V4L2 tests
# need ioctls that qemu-user does not translate; Debian 12's qemu-user (7.2)
# never returns from creating a second thread, so the tests that start one
# run natively only. A test that still hangs fails after 10 minutes.
skip='V4l2Source|NoMallocDeathTest|SpscQueue.OneProducerAndOneConsumer'
if [ "${2:-}" = "all" ]; then
  cmake --build "$build" -j"$(nproc)"
  ctest --test-dir "$build" -LE vcan -E "$skip" -j"$(nproc)" --timeout 3000 --output-on-failure
  exit 0
fi
units=(common_test solver_model_test solver_pose_test solver_no_malloc_test can_iface_test hal_can_test
       hal_clock_test hal_camera_test)
cmake --build "$build" -j"$(nproc)" --target tcpest "${units[@]}"
ctest --test-dir "$build" -LE vcan -E "$skip|_NOT_BUILT" -j"$(nproc)" --timeout 600 --output-on-failure

out="$(mktemp -d)"
trap 'rm -rf "$out"' EXIT
"$host_tcpest" render --set hard --seed 1 --n 12 --out "$out/host" --quiet
"${arm_tcpest[@]}" render --set hard --seed 1 --n 12 --out "$out/arm" --quiet
diff -r "$out/host" "$out/arm"
echo "the hard set's first 12 frames: the same bytes from both builds"
strip_times() { sed -E 's/"time_us": [0-9]+//'; }
"$host_tcpest" estimate --json "$out"/host/*.jpg | strip_times >"$out/host.jsonl"
"${arm_tcpest[@]}" estimate --json "$out"/host/*.jpg | strip_times >"$out/arm.jsonl"
diff "$out/host.jsonl" "$out/arm.jsonl"
echo "their estimates: the same from both builds ($(wc -l <"$out/host.jsonl") frames)"
