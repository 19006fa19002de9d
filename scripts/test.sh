#!/usr/bin/env bash
# Quick start, second command: install what is missing, build and run the whole test suite.
# AREOMAP_PRESET picks the CMake preset (release by default; CI uses "ci" for -Werror and
# "asan" for AddressSanitizer + UndefinedBehaviorSanitizer).
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${AREOMAP_PRESET:-release}"
# Paths relative to the checkout, so ccache hits across clones (CI builds a fresh one).
export CCACHE_BASEDIR="${CCACHE_BASEDIR:-$PWD}"

bash scripts/install-deps.sh
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset"
ctest --preset "$preset"
