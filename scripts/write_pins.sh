#!/usr/bin/env bash
# Rewrites the fp32 pins (tests/learn/pins/trainer-fp32.txt: the short training run's weights
# digest; tests/tools/golden/FAMILY/: the pinned evaluation) for the families of fp32 kernels this
# machine can run: its own, and on a CPU with AVX-512 also "avx2" through the stand-in for an
# AVX2-only CPU (oneDNN and ATen capped to AVX2, which reproduces an AVX2-only EPYC bit for bit).
# Run it after a change that is meant to change fp32 results, and commit the pins with the change
# saying why. Needs a Release build in build/ (./scripts/setup.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
cmake --build build -j"$(nproc)" --target learn_tests tools_tests scout
pins='TrainerPin\.|TrainerGradientHook\.AnIdentityHook|EvalCommand\.ThePinnedReport'
caps=(-u ONEDNN_MAX_CPU_ISA -u DNNL_MAX_CPU_ISA -u ATEN_CPU_CAPABILITY)  # a cap inherited would mix families
run() {  # ENV...: the pin tests in write mode, then again comparing
  env "${caps[@]}" "$@" SCOUT_WRITE_PINS=1 ctest --test-dir build -R "$pins" --no-tests=error --output-on-failure
  env "${caps[@]}" "$@" ctest --test-dir build -R "$pins" --no-tests=error --output-on-failure
}
run
flags=$(grep -m1 '^flags' /proc/cpuinfo)
if [[ $flags == *" avx512f "* && $flags == *" avx512bw "* && $flags == *" avx512vl "* && $flags == *" avx512dq "* ]]; then
  run ONEDNN_MAX_CPU_ISA=AVX2 ATEN_CPU_CAPABILITY=avx2  # the stand-in for an AVX2-only CPU
fi
git status --short tests/learn/pins tests/tools/golden
