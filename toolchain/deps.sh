#!/usr/bin/env bash
# Installs the Debian 12 packages a tcpest job needs, only those missing.
# Usage: source toolchain/deps.sh; tcpest_install_deps PKG...
tcpest_install_deps() {
  local missing=()
  local pkg
  for pkg in "$@"; do
    if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
      missing+=("$pkg")
    fi
  done
  if [ "${#missing[@]}" -eq 0 ]; then
    return 0
  fi
  echo "tcpest: installing Debian packages: ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    sudo="sudo"
  fi
  $sudo apt-get update -qq || return 1
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" || return 1
}

# What building and running tcpest needs.
TCPEST_BUILD_PACKAGES=(cmake make g++ libeigen3-dev libjpeg62-turbo-dev libturbojpeg0-dev pkg-config)
# What the tests and checks need on top (dpkg-dev and file: cpack's Debian
# package and its dependencies; gcovr: the coverage floor,
# toolchain/coverage.sh; libclang-rt-14-dev: libFuzzer and the
# sanitizer runtimes of clang 14, toolchain/fuzz.sh).
TCPEST_TEST_PACKAGES=(libgtest-dev libgmock-dev libbenchmark-dev clang libclang-rt-14-dev clang-tidy cppcheck
                      can-utils user-mode-linux kmod iproute2 python3 g++-aarch64-linux-gnu
                      dpkg-dev file gcovr)
# The vcan tests' qemu guest (tests/vcan/README.md), x86-64 hosts only; its
# kernel is fetched by run-vcan.sh with apt-get download, not installed.
if [ "$(uname -m)" = "x86_64" ]; then
  TCPEST_TEST_PACKAGES+=(qemu-system-x86 busybox-static)
fi
# Optional peer libraries, only for the comparison benchmarks (vision_bench
# compares stage 1 with OpenCV); nothing else needs them.
TCPEST_PEER_PACKAGES=(libopencv-dev)
