#!/usr/bin/env bash
# Line and branch coverage of the core units (common, solver, vision,
# can_iface, the loop) by their own tests, and the floor CI enforces:
# at least 90 % of lines and 75 % of branches. GCC's gcov through gcovr, the
# `coverage` preset (--coverage -Og: optimised enough that the image tests
# run in about a minute, close enough to the source for line counts).
# Branches the compiler adds for exceptions and unreachable code are not
# counted (the core units are built without exceptions).
# Writes build/coverage/coverage.txt (per file, uncovered lines) and prints
# the summary. Usage: toolchain/coverage.sh
set -euo pipefail
cd "$(dirname "$0")/.."
readonly min_lines=90
readonly min_branches=75
# The core units: their sources are measured, their tests run.
readonly units=(common solver vision can_iface firmware_like/loop)
jobs="$(nproc)"

cmake --preset coverage >/dev/null
mapfile -t test_targets < <(for unit in "${units[@]}"; do
  sed -n 's/.*tcpest_test(NAME \([A-Za-z0-9_]*\).*/\1/p' "$unit/test/CMakeLists.txt"
done)
echo "coverage: building ${test_targets[*]}"
cmake --build build/coverage -j"$jobs" --target "${test_targets[@]}"
find build/coverage -name '*.gcda' -delete
for unit in "${units[@]}"; do
  ctest --test-dir "build/coverage/$unit" -j"$jobs" -LE vcan --output-on-failure | tail -n 3
done
filters=()
for unit in "${units[@]}"; do
  filters+=(--filter "$unit/src/" --filter "$unit/include/")
done
# --gcov-ignore-parse-errors: tests of one program running in parallel can
# leave a garbled count in gcov's output, which would otherwise stop gcovr.
gcovr --root . build/coverage "${filters[@]}" --exclude-unreachable-branches --exclude-throw-branches \
  --gcov-ignore-parse-errors \
  -j"$jobs" --txt build/coverage/coverage.txt --print-summary \
  --fail-under-line "$min_lines" --fail-under-branch "$min_branches" || {
  echo "coverage: below the floor ($min_lines % lines, $min_branches % branches): build/coverage/coverage.txt"
  exit 1
}
echo "coverage: at or above the floor ($min_lines % lines, $min_branches % branches)"
