#!/usr/bin/env bash
# The sanitizer pass, for CI (.ci/run runs it after the tests) and for contributors before a
# change to threads, buffers or file parsing:
#
#   scripts/sanitize.sh [address|thread|all]     (default: all)
#
# address: the whole project built again with AddressSanitizer and UndefinedBehaviorSanitizer
#   (build-asan/), then the test suite: every C++ test and the Python tests (the interpreter is
#   not instrumented, so ASan's runtime is preloaded for them; tests/python/CMakeLists.txt).
# thread: the project built with ThreadSanitizer (build-tsan/), then the tests of the code that
#   runs threads or processes: the worker pool and the batched physics (sim_tests), the camera
#   (render_tests) and multi-process training (the TrainDistributed tests, two processes over
#   Gloo). The rest of the suite is single-threaded on Scout's side (LibTorch's own threads are
#   not instrumented, so TSan could not see into them anyway).
#
# Every report fails the run (no recovery). What is suppressed, and why, is in
# scripts/sanitizers/*.supp: only other libraries' own leaks at exit, never Scout's code.
set -euo pipefail
cd "$(dirname "$0")/.."
which=${1:-all}
case "$which" in address|thread|all) ;; *) echo "usage: $0 [address|thread|all]" >&2; exit 2 ;; esac
jobs=$(nproc)
supp="$PWD/scripts/sanitizers"
warnings=${SCOUT_WARNINGS_AS_ERRORS:-OFF}

export ASAN_OPTIONS="abort_on_error=1:detect_leaks=1:check_initialization_order=1:detect_stack_use_after_return=0"
export LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:suppressions=$supp/tsan.supp"

configure_and_build() {  # folder, sanitizers
  # -O1: the sanitizers' usual level (fast enough to run the suite, and it compiles in half the time of -O3).
  cmake -S . -B "$1" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DSCOUT_SANITIZE="$2" \
    -DSCOUT_WARNINGS_AS_ERRORS="$warnings" >/dev/null
  cmake --build "$1" -j"$jobs"
}

if [[ "$which" == address || "$which" == all ]]; then
  start=$SECONDS
  configure_and_build build-asan address,undefined
  ctest --test-dir build-asan --output-on-failure -j"$jobs"
  echo "sanitize: AddressSanitizer + UndefinedBehaviorSanitizer: whole suite passed in $((SECONDS - start)) s"
fi

if [[ "$which" == thread || "$which" == all ]]; then
  start=$SECONDS
  configure_and_build build-tsan thread
  # TSan maps its shadow memory at fixed addresses, which the kernel's address-space layout
  # randomisation can collide with (Linux 6.x with 32 random mmap bits): run without it.
  setarch "$(uname -m)" -R ctest --test-dir build-tsan --output-on-failure -j"$jobs" \
    -R '^(WorkerPool|RobotBatch|PatchCamera|CropPatch|BatchEnv|VectorEnvTest|TrainDistributed)\.'
  echo "sanitize: ThreadSanitizer: worker pool, physics, camera and multi-process tests passed in $((SECONDS - start)) s"
fi
