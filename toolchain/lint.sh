#!/usr/bin/env bash
# clang-tidy (config: .clang-tidy) and cppcheck over the first-party sources
# of a configured build (its compile_commands.json), after a check that no
# product code calls libm's transcendental functions. Fails on any finding.
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build/default}"
mapfile -t sources < <(git ls-files '*.cpp' | grep -E '^(common|solver|vision|can_iface|hal|firmware_like)/' | grep -v '/test/')
if [ "${#sources[@]}" -eq 0 ]; then
  echo "lint: no sources"; exit 0
fi
# Reproducible arithmetic (docs/architecture.md): product code calls
# tcpest::dmath, never libm's transcendental functions, whose last bit
# depends on the CPU. Tests may call libm (dmath's own tests compare with it).
mapfile -t product_code < <(git ls-files '*.cpp' '*.hpp' | grep -E '^(common|solver|vision|can_iface|hal|firmware_like)/' |
                            grep -v -E '/test/|/bench/')
libm_pattern='std::(sin|cos|tan|asin|acos|atan|atan2|sinh|cosh|tanh|exp|exp2|expm1|log|log2|log10|log1p|pow|cbrt|hypot|erf|erfc|tgamma|lgamma)[[:space:]]*\('
if grep -n -E "$libm_pattern" "${product_code[@]}"; then
  echo "lint: libm's transcendental functions above; call tcpest::dmath (common/include/tcpest/common/dmath.hpp)"
  exit 1
fi
echo "clang-tidy: ${#sources[@]} files"
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
tidy_status=0
# xargs exits non-zero when any clang-tidy run reported a finding.
# -Wcomma (clang-diagnostic-comma in .clang-tidy): no comma operator
# (docs/coding-rules.md, MISRA C:2012 rule 12.3).
printf '%s\n' "${sources[@]}" | xargs -P "$(nproc)" -n 4 clang-tidy -p "$build" --quiet --warnings-as-errors='*' \
  --extra-arg=-Wcomma \
  >"$log" 2>&1 || tidy_status=1
grep -v -E '^[0-9]+ warnings? generated|^Suppressed [0-9]+ warnings|^Use -header-filter' "$log" || true
if [ "$tidy_status" -ne 0 ]; then
  echo "clang-tidy: findings above"; exit 1
fi
echo "cppcheck: ${#sources[@]} files"
includes=()
for dir in common/include solver/include vision/include can_iface/include hal/*/include firmware_like/src; do
  [ -d "$dir" ] && includes+=("-I$dir")
done
# Eigen and system headers are not analysed (missingIncludeSystem): they are
# not ours, and parsing Eigen would take most of the CI budget.
cppcheck -j "$(nproc)" --std=c++17 --language=c++ --enable=warning,performance,portability --inline-suppr \
  --error-exitcode=1 --quiet --suppress=missingIncludeSystem \
  --suppressions-list=toolchain/cppcheck-suppressions.txt "${includes[@]}" "${sources[@]}"
echo "lint: clean"
