#!/usr/bin/env bash
# Checks that tcpest installs and can be built against (docs/install.md):
# installs a configured, built tree (default build/default) into a throwaway
# prefix, builds tests/consumer against it with CMake (find_package) and with
# pkg-config, and checks that both give the same pose as `tcpest solve` on
# the same corners, that the CAN TCP message carries it, and that the
# arithmetic flags reached the consumer's compile line. Builds nothing of
# tcpest itself beyond bringing the installed targets up to date.
# Usage: toolchain/check-install.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build/default}"
[ -f "$build/CMakeCache.txt" ] || { echo "check-install: $build is not a configured build"; exit 1; }
cmake --build "$build" -j"$(nproc)" --target tcpest tcpest_loop >/dev/null
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
prefix="$tmp/prefix"
fail() { echo "check-install: $*"; exit 1; }

echo "install into a throwaway prefix"
cmake --install "$build" --prefix "$prefix" >"$tmp/install.log"
libdir="$(sed -n 's/^CMAKE_INSTALL_LIBDIR:PATH=//p' "$build/CMakeCache.txt")"
for f in bin/tcpest include/tcpest/solver/pose_solver.hpp include/tcpest/can_iface/messages.hpp \
         include/tcpest/vision/frame_estimator.hpp include/tcpest/common/result.hpp \
         include/tcpest/loop/config.hpp include/tcpest/hal/camera/frame_source.hpp include/tcpest/hal/can/bus.hpp \
         include/tcpest/hal/clock/clock.hpp "$libdir/libtcpest_solver.a" "$libdir/libtcpest_common.a" \
         "$libdir/libtcpest_loop.a" "$libdir/cmake/tcpest/tcpestConfig.cmake" \
         "$libdir/cmake/tcpest/tcpestConfigVersion.cmake" "$libdir/pkgconfig/tcpest.pc" \
         share/tcpest/config/deploy.yaml share/tcpest/config/pal_camera.yaml share/tcpest/config/instrument.yaml \
         share/doc/tcpest/tcpest.dbc share/doc/tcpest/install.md lib/systemd/system/tcpest.service; do
  [ -e "$prefix/$f" ] || fail "$f not installed"
done
# The flight libraries only: no renderer, no simulation headers.
for f in include/tcpest/render include/tcpest/loop/rendered_scene.hpp "$libdir/libtcpest_hal_render.a" \
         "$libdir/libtcpest_cli.a"; do
  [ ! -e "$prefix/$f" ] || fail "$f installed (simulation or tools code)"
done

echo "build tests/consumer with find_package(tcpest 1.0)"
cmake -S tests/consumer -B "$tmp/consumer" -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH="$prefix" >"$tmp/consumer.log" ||
  { cat "$tmp/consumer.log"; fail "consumer configuration failed"; }
cmake --build "$tmp/consumer" >>"$tmp/consumer.log" || { cat "$tmp/consumer.log"; fail "consumer build failed"; }
# Reproducible arithmetic reaches the consumer's code (docs/architecture.md).
for flag in -ffp-contract=off -DEIGEN_DONT_VECTORIZE; do
  grep -q -- "$flag" "$tmp/consumer/compile_commands.json" || fail "consumer compiled without $flag"
done

echo "build it with pkg-config"
pc_flags="$(PKG_CONFIG_PATH="$prefix/$libdir/pkgconfig" pkg-config --cflags --libs tcpest)"
for flag in -ffp-contract=off -DEIGEN_DONT_VECTORIZE -ltcpest_solver -ltcpest_common -ljpeg; do
  [[ " $pc_flags " == *" $flag "* ]] || fail "pkg-config gives no $flag: $pc_flags"
done
# The include directory is found from the .pc file's place (relocatable).
found=0
for include_dir in $(tr ' ' '\n' <<<"$pc_flags" | sed -n 's/^-I//p'); do
  [ "$(realpath -m "$include_dir")" = "$(realpath "$prefix/include")" ] && found=1
done
[ "$found" -eq 1 ] || fail "pkg-config gives no -I to the prefix's include directory: $pc_flags"
# shellcheck disable=SC2086  # pkg-config's output is a list of words
c++ -std=c++17 -O2 tests/consumer/main.cpp -o "$tmp/consumer-pc" $pc_flags || fail "pkg-config build failed: $pc_flags"

echo "compare with tcpest solve"
tcpest="$prefix/bin/tcpest"
"$tcpest" --version
# Two configurations (x_ch, y_ch, psi, mu, lambda, phi, theta): README's and a bent one.
for r in -13.3,6.2,0.1745,0,20,0.3,0.8 -12.9,6.6,0.19,0.02,28,-0.7,1.1; do
  "$tcpest" project --r "$r" >"$tmp/project.json"
  corners="$(python3 -c 'import json,sys; print(json.dumps({"corners": json.load(sys.stdin)["corners"]}))' <"$tmp/project.json")"
  mapfile -t args < <(python3 -c '
import json, sys
for c in json.load(sys.stdin)["corners"]:
    print("nan" if c is None else repr(c[0])); print("nan" if c is None else repr(c[1]))' <"$tmp/project.json")
  echo "$corners" | "$tcpest" solve --corners - >"$tmp/solve.json"
  config="$prefix/share/tcpest/config/deploy.yaml"
  "$tmp/consumer/tcpest_consumer" "$config" "${args[@]}" >"$tmp/cmake-consumer.txt"
  "$tmp/consumer-pc" "$config" "${args[@]}" >"$tmp/pc-consumer.txt"
  cmp -s "$tmp/cmake-consumer.txt" "$tmp/pc-consumer.txt" || fail "the CMake and pkg-config builds disagree"
  python3 - "$tmp/solve.json" "$tmp/cmake-consumer.txt" <<'EOF' || fail "consumer and tcpest solve disagree (r $r)"
import json, sys
solve = json.load(open(sys.argv[1]))
lines = [json.loads(line) for line in open(sys.argv[2])]
consumer, can, config = lines
if consumer != solve:
    sys.exit(f"tcpest solve: {solve}\nconsumer:     {consumer}")
lsb_mm = 0.01  # the TCP message's length resolution (docs/can-protocol.md)
if can["can_id"] != 0x190 or can["status"] != "valid" or \
        any(abs(a - b) > lsb_mm / 2 + 1e-9 for a, b in zip(can["tcp"], solve["tcp"])):
    sys.exit(f"CAN TCP message {can} does not carry {solve['tcp']}")
if config != {"bus": "can0", "cpu": 3}:
    sys.exit(f"deploy.yaml read as {config}")
print(f"  {solve['status']}, tcp {solve['tcp']} mm: consumer (CMake and pkg-config) identical; CAN {can['tcp']}")
EOF
done
echo "check-install: OK"
