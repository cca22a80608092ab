#!/usr/bin/env bash
# Checks tcpest's Debian package (docs/install.md): makes it with
# `cpack -G DEB` from a configured, built tree (default build/default) into a
# throwaway folder, checks its contents and metadata (the files an
# integrator and the service need; dependencies on runtime packages only,
# never on -dev packages or build tools), unpacks it and runs the binary
# from there: --help, --version and `tcpest solve` on corners of
# `tcpest project`, compared with the build's own tcpest.
# Usage: toolchain/check-package.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build="$(realpath "${1:-build/default}")"
[ -f "$build/CPackConfig.cmake" ] || { echo "check-package: $build is not a configured build"; exit 1; }
cmake --build "$build" -j"$(nproc)" --target tcpest tcpest_loop >/dev/null
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail() { echo "check-package: $*"; exit 1; }

echo "cpack -G DEB"
(cd "$tmp" && cpack -G DEB --config "$build/CPackConfig.cmake" -B "$tmp/out" >"$tmp/cpack.log") ||
  { cat "$tmp/cpack.log"; fail "cpack failed"; }
deb="$(ls "$tmp"/out/tcpest_*.deb)"
echo "  $(basename "$deb")"

dpkg-deb -I "$deb" >"$tmp/info.txt"
dpkg-deb -c "$deb" | awk '{print $NF}' >"$tmp/contents.txt"
grep -q '^ Package: tcpest$' "$tmp/info.txt" || fail "not package tcpest: $(cat "$tmp/info.txt")"
grep -q '^ Version: 1\.' "$tmp/info.txt" || fail "version not 1.x: $(grep Version "$tmp/info.txt")"
depends="$(sed -n 's/^ Depends: //p' "$tmp/info.txt")"
echo "  Depends: $depends"
for pkg in libc6 libstdc++6 libgcc-s1 libjpeg62-turbo; do
  [[ ", $depends" == *", $pkg "* || ", $depends," == *", $pkg,"* ]] || fail "Depends lacks $pkg"
done
# Runtime only: no headers' packages, no compilers or build tools.
if tr ',' '\n' <<<"$depends" | grep -E -e '-dev\b' -e '^ *(cmake|make|g\+\+|gcc|clang|pkg-config|dpkg-dev|build-essential)( |$)'; then
  fail "Depends names a -dev package or a build tool"
fi
for f in ./usr/bin/tcpest ./usr/lib/libtcpest_solver.a ./usr/lib/libtcpest_can_iface.a ./usr/lib/libtcpest_loop.a \
         ./usr/include/tcpest/solver/pose_solver.hpp ./usr/include/tcpest/can_iface/messages.hpp \
         ./usr/lib/cmake/tcpest/tcpestConfig.cmake ./usr/lib/pkgconfig/tcpest.pc \
         ./usr/share/tcpest/config/deploy.yaml ./usr/share/tcpest/config/pal_camera.yaml \
         ./usr/share/doc/tcpest/tcpest.dbc ./usr/share/doc/tcpest/loop.md ./usr/share/doc/tcpest/install.md \
         ./usr/lib/systemd/system/tcpest.service; do
  grep -qx -- "$f" "$tmp/contents.txt" || fail "$f not in the package"
done

echo "unpack and run"
dpkg-deb -x "$deb" "$tmp/root"
tcpest="$tmp/root/usr/bin/tcpest"
"$tcpest" --help >/dev/null || fail "tcpest --help failed"
"$tcpest" --version
unit="$tmp/root/usr/lib/systemd/system/tcpest.service"
# The unit's paths are the package's (the unit may name them; they must exist).
grep -o -E '/usr/[^ ]+' "$unit" | grep -v '^/usr/share/doc/' | sort -u |
  while read -r path; do
    [ -e "$tmp/root$path" ] || fail "tcpest.service names $path, not in the package"
  done
# The unit's settings that the deployment relies on (docs/loop.md, "Deployment").
for setting in '^Restart=on-failure$' '^StartLimitBurst=' '^StartLimitIntervalSec=' '^SuccessExitStatus=4$' \
               '^CPUAffinity=' '^LimitMEMLOCK=infinity$' '^LimitRTPRIO=' '^ExecStartPre=.*ip link set can0 up type can bitrate' \
               '^ExecStart=/usr/bin/tcpest run --config /usr/share/tcpest/config/deploy.yaml'; do
  grep -q -E "$setting" "$unit" || fail "tcpest.service has no line matching $setting"
done
"$build/firmware_like/tcpest" project --r -13.3,6.2,0.1745,0,20,0.3,0.8 >"$tmp/project.json"
"$tcpest" solve --corners "$tmp/project.json" >"$tmp/packaged.json"
"$build/firmware_like/tcpest" solve --corners "$tmp/project.json" >"$tmp/built.json"
cmp -s "$tmp/packaged.json" "$tmp/built.json" || fail "the packaged tcpest solves otherwise than the build's"
echo "  solve: $(cat "$tmp/packaged.json")"
echo "check-package: OK"
