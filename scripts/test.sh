#!/usr/bin/env bash
# Sets up (Debian packages), builds and runs the whole test suite (CTest + GTest).
set -euo pipefail
cd "$(dirname "$0")/.."
./scripts/build.sh
BUILD_DIR=${BUILD_DIR:-build}
cd "$BUILD_DIR"
ctest --output-on-failure -j "$(nproc)" --timeout 900
