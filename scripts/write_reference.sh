#!/usr/bin/env bash
# Rewrites the fp32 references: the reference training run's weights
# (tests/learn/pins/trainer-fp32-weights.txt) and the reference evaluation (tests/tools/golden/).
# The tests compare every CPU's results with them within tolerances derived from fp32's rounding
# (their comments), so they are written once, on any machine. Run it after a change that is meant
# to change fp32 results, and commit them with the change saying why. Needs a Release build in
# build/ (./scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --build build -j"$(nproc)" --target learn_tests tools_tests scout
tests='TrainerReference\.|EvalCommand\.TheReferenceReport'
SCOUT_WRITE_REFERENCE=1 ctest --test-dir build -R "$tests" --no-tests=error --output-on-failure
ctest --test-dir build -R "$tests" --no-tests=error --output-on-failure
git status --short tests/learn/pins tests/tools/golden
