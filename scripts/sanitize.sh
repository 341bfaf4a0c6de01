#!/usr/bin/env bash
# The sanitizer pass, for CI and for contributors before a change to threads, buffers or file
# parsing:
#
#   scripts/sanitize.sh [address|thread|all|ci] [STEP]     (default: all, every step)
#
# STEP (build-address, test-address, build-thread or test-thread) runs one step alone: .ci/run
# builds each sanitizer's tree at idle priority while the tests before it run.
#
# address: the whole project built again with AddressSanitizer and UndefinedBehaviorSanitizer
#   (build-asan/), then the whole test suite: every C++ test and the Python tests (the interpreter
#   is not instrumented, so ASan's runtime is preloaded for them; tests/python/CMakeLists.txt).
#   About 11 minutes of building and 35 of testing on 2 cores.
# thread: the tests of the code that runs threads or processes, built with ThreadSanitizer
#   (build-tsan/): the worker pool (core), the batched physics (sim), the camera (render), the
#   batched environment (env, whose observing shares the physics' pool) and multi-process training (TrainDistributed: two or three `scout`
#   processes over Gloo, each with its worker pool). The rest of the suite is single-threaded on
#   Scout's side; LibTorch's own threads are not instrumented, so TSan could not see into them.
# all: address, then thread.
# ci: what .ci/run runs after the test suite, within its time: `address` on a labelled subset and
#   `thread` on a subset of the multi-process tests (both below), building only what they run.
#   The ASan subset's tests run through scripts/sanitizers/run_grouped.py: each test program is
#   started once per shard rather than once per test (a program that links LibTorch takes 2.5 s
#   to start under ASan); the same tests, in the same folders, with the same environment.
#
# The ASan subset (ci): every test labelled core, grid, worlds, sim, render, env, agent, learn or
# python: the loaders and their fuzzers, the physics, the camera, the networks, the checkpoints
# and the Python package with its examples; and eleven of the `tools` label's end-to-end tests
# (ASAN_CI_TOOLS_TESTS), which run the `scout` program instrumented: its command line, output
# folder, training, evaluation, report and multi-process launcher. Left out:
#   - the rest of the `tools` label (more runs, kills, full disks): they drive the same code through
#     the command line, take 14 of the 35 minutes under ASan, and the full `address` pass runs them;
#   - SLOW_UNDER_ASAN: learning runs and gradient checks of 30-90 s each under ASan, and the
#     Python examples (REINFORCE's 250 training batches take minutes under ASan). Shorter
#     tests run the same code (rollouts, the estimator, the trainer, ResNet-18, the Python
#     package's vector environment and agent in test_scout_env.py); these only run it longer.
# test_scout_env.py compares the package with the Release build's program, as its reference.
#
# Every process's sanitizer output goes to a log file of its own (with_sanitizer_logs below): the
# step then prints the matched suppressions with their counts and fails on any report, whichever
# process wrote it (a test, a `scout` it started, a rank, a forked child, the Python interpreter).
#
# The TSan subset (ci): the worker pool, physics, camera and environment tests, and four of the ten
# TrainDistributed tests, which between them run every multi-process path: training with its
# all-reduces and checkpoints (TwoProcessesTrainTheSameWeightsAsOne), a lost rank and the
# survivors' stop and resume (ALostRank...), Ctrl-C across processes (ControlC...) and evaluation
# over processes (EvalOverTwoProcesses...). Left out (TSan multiplies their minutes): a second
# identical run (TheSameProcessCountTwice...), the other lost-rank case (LosingRankZero...), the
# rendezvous timeouts (ARankThatNeverArrives..., AWrongPort...: one thread waiting 10 s) and the
# refusals before training starts (RanksThatDisagree..., ResumingWithAnotherProcessCount...).
#
# Every report fails the run (no recovery). What is suppressed, and why, is in
# scripts/sanitizers/*.supp, by function, each with the report it answers: other libraries' own
# allocations kept until exit, and races whose synchronisation is inside LibTorch, Gloo or libgomp
# (not built with TSan); never a frame of Scout's code.
set -euo pipefail
cd "$(dirname "$0")/.."
which=${1:-all}
step=${2:-}
usage="usage: $0 [address|thread|all|ci] [build-address|test-address|build-thread|test-thread]"
case "$which" in address|thread|all|ci) ;; *) echo "$usage" >&2; exit 2 ;; esac
case "$step" in ""|build-address|test-address|build-thread|test-thread) ;; *) echo "$usage" >&2; exit 2 ;; esac
[[ -z "$step" || "$step" == *-address && "$which" != thread || "$step" == *-thread && "$which" != address ]] ||
  { echo "$usage" >&2; exit 2; }
jobs=$(nproc)
supp="$PWD/scripts/sanitizers"
warnings=${SCOUT_WARNINGS_AS_ERRORS:-OFF}

# Each test step adds log_path (sanitizer_logs below); the matched suppressions are printed at
# every process's exit into its log, and summarized in the step's output.
# LibTorch's OpenMP threads wait passively, as under ctest (tests/CMakeLists.txt says why); the
# grouped ASan runs start the test programs themselves, so it is set here for them too.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-PASSIVE}
export ASAN_OPTIONS="abort_on_error=1:detect_leaks=1:check_initialization_order=1:detect_stack_use_after_return=0"
export LSAN_OPTIONS="suppressions=$supp/lsan.supp:print_suppressions=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:history_size=7:suppressions=$supp/tsan.supp:print_suppressions=1"

ASAN_CI_LABELS='^(core|grid|worlds|sim|render|env|agent|learn|python)$'
# The test programs the subset runs, and the `scout` program (the hostile-checkpoint corpus and the
# tools tests below run it; the Python tests run the Release build's as their reference). The
# tools tests' own programs only start `scout` and read what it wrote, so the Release build's run
# them, against this tree's instrumented `scout` (SCOUT_TEST_PROGRAM: tests/support/cli.hpp),
# instead of a second build of their 23 files.
ASAN_CI_TARGETS=(core_tests grid_tests worlds_tests sim_tests render_tests render_camera_tests render_backend_tests env_tests
                 agent_tests learn_tests
                 scout_python scout_python_agent scout)
# The `scout` program's own code (tools/) under ASan, in a few of its end-to-end tests: the command
# line and its refusals, the output folder and --overwrite, a run's pictures, a training run with
# its checkpoint, Ctrl-C and resume, evaluation, the report (with its plotting child), and the
# multi-process launcher with two ranks.
ASAN_CI_TOOLS_TESTS=(Cli.HelpVersionAndUsageErrors Cli.AnExistingOutputFolderIsRefusedUnlessOverwriting
  Cli.OverwriteNeverDestroysWhatIsNotScoutOutput Cli.RunWritesTrajectoryImagesAndManifest
  TrainCli.ATinyRunWritesCheckpointMetricsAndManifest TrainCli.BadOptionsAreRefusedWithOneLine
  TrainCli.ControlCSavesACheckpointThatResumeFinishes EvalRun.EvalPrintsATableAndWritesTheReportAndPredictions
  EvalRun.ReportEvaluatesAndDrawsTheTableAndFigures EvalRun.ReportRefusesBadInputsWithOneLine
  TrainDistributed.TwoProcessesTrainTheSameWeightsAsOne)
SLOW_UNDER_ASAN='^(Training\.(LearnedGoalsFindTheCornerThatIidGoalsMiss|ResNet18LearnsSyntheticDigits)|EstimatorGradient\.(TwoEpisodesModeIII.*|ModeIIIMatchesExactGradient)|TrainerGradientHook\..*|Precision\.Bf16AccumulatesThePlannersGradientsOverMovesLikeFp32|Python\.test_examples)$'
TSAN_TESTS='^(osmesa\.)?(WorkerPool|RobotBatch|PatchCamera|CropPatch|BatchEnv|VectorEnvTest|TrainDistributed)\.'
TSAN_CI_TESTS='^((osmesa\.)?(WorkerPool|RobotBatch|PatchCamera|CropPatch|BatchEnv|VectorEnvTest)\..*|TrainDistributed\.(TwoProcessesTrainTheSameWeightsAsOne|ALostRankStopsTheOthersWithinTheTimeoutAndResumeFinishes|ControlCStopsEveryProcessAfterRankZeroSavesACheckpoint|EvalOverTwoProcessesGivesTheSameReport))$'
# The multi-process tests run from the Release build's tools_process_tests against this tree's
# instrumented `scout`, as the ASan subset's tools tests do.
TSAN_TARGETS=(core_tests sim_tests render_camera_tests env_tests scout)
# What each of those regexes must still find (a renamed test would otherwise drop out unseen).
TSAN_FAMILIES=('^WorkerPool\.' '^RobotBatch\.' '^osmesa\.PatchCamera\.' '^osmesa\.CropPatch\.' '^BatchEnv\.' '^VectorEnvTest\.')
TSAN_CI_NAMED=('^TrainDistributed\.TwoProcessesTrainTheSameWeightsAsOne$'
  '^TrainDistributed\.ALostRankStopsTheOthersWithinTheTimeoutAndResumeFinishes$'
  '^TrainDistributed\.ControlCStopsEveryProcessAfterRankZeroSavesACheckpoint$'
  '^TrainDistributed\.EvalOverTwoProcessesGivesTheSameReport$')

# ctest's own timings of a test step, for CI's time table (.ci/run sets SCOUT_CI_JUNIT).
junit() {  # NAME: ctest's option to write them, where CI asks
  [[ -n "${SCOUT_CI_JUNIT:-}" ]] && echo "--output-junit $SCOUT_CI_JUNIT/$1.xml"
  true
}

# Stops with one line when a pattern matches no test of the build folder.
require_tests() {  # folder pattern...
  local folder=$1 pattern count
  shift
  for pattern in "$@"; do
    count=$(ctest --test-dir "$folder" -N -R "$pattern" | sed -n 's/^Total Tests: //p')
    if [[ "${count:-0}" -eq 0 ]]; then
      echo "sanitize: no test in $folder matches $pattern (renamed or removed? update scripts/sanitize.sh)" >&2
      exit 1
    fi
  done
}

# Runs a test command with every process's sanitizer output in FOLDER/sanitizer-logs (log_path:
# one file per process, whichever test, rank or child it is and whoever reads its stderr), then
# summarizes those logs (scripts/sanitizers/summarize_logs.py): the matched suppressions with their
# counts, and every report, which fails the step even where its process exited as its test
# expected. The command's own failure fails the step too, after the summary.
with_sanitizer_logs() {  # folder suppression-files command...
  local logs="$PWD/$1/sanitizer-logs" files=$2 status=0 summary=0
  shift 2
  rm -rf "$logs" && mkdir -p "$logs"
  ASAN_OPTIONS="$ASAN_OPTIONS:log_path=$logs/asan" UBSAN_OPTIONS="$UBSAN_OPTIONS:log_path=$logs/ubsan" \
    TSAN_OPTIONS="$TSAN_OPTIONS:log_path=$logs/tsan" "$@" || status=$?
  # shellcheck disable=SC2086  # the suppression files, split on purpose
  /usr/bin/python3 scripts/sanitizers/summarize_logs.py "$logs" $files || summary=$?
  ((status == 0 && summary == 0))
}

# Ninja for new build folders, as scripts/setup.sh.
export CMAKE_GENERATOR=${CMAKE_GENERATOR:-Ninja}

configure() {  # folder, sanitizers, [more cmake options...]
  # -O1: the sanitizers' usual level (fast enough to run the suite, and it compiles in half the time of -O3).
  cmake -S . -B "$1" -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_FLAGS_RELEASE="-O1 -DNDEBUG" -DSCOUT_SANITIZE="$2" \
    -DSCOUT_WARNINGS_AS_ERRORS="$warnings" "${@:3}" >/dev/null
}
build() {  # folder [targets...]
  local folder=$1
  shift
  if (($#)); then cmake --build "$folder" -j"$jobs" --target "$@"; else cmake --build "$folder" -j"$jobs"; fi
}

# The ASan subset of CI: the labelled tests, grouped, then the tools/ tests one by one (some run
# serially: several processes, or a kill); both run whatever the other's result.
asan_ci_tests() {  # tools-regex [--costs FILE]
  local tools_regex=$1 status=0
  shift
  /usr/bin/python3 scripts/sanitizers/run_grouped.py build-asan "$jobs" "$@" -L "$ASAN_CI_LABELS" \
    -E "$SLOW_UNDER_ASAN" || status=$?
  # shellcheck disable=SC2046  # junit's option and its path, split on purpose
  SCOUT_TEST_PROGRAM="$PWD/build-asan/tools/scout" ctest --test-dir build --output-on-failure --no-tests=error \
    -j"$jobs" -R "$tools_regex" $(junit asan-tools) || status=$?
  return "$status"
}

address() {  # build|test
  local start=$SECONDS
  if [[ "$which" == ci ]]; then
    if [[ "$1" == build ]]; then
      # The Python tests' reference program and the tools tests' programs: the Release build's,
      # brought up to date first, except in a step of .ci/run, which has just built them and runs
      # their tests meanwhile.
      if [[ -z "$step" ]]; then
        cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
        build build scout tools_tests tools_process_tests
      elif [[ ! -x build/tools/scout ]]; then
        echo "sanitize: build/tools/scout is missing: run scripts/setup.sh first" >&2
        exit 1
      fi
      configure build-asan address,undefined -DSCOUT_PYTHON_REFERENCE_PROGRAM="$PWD/build/tools/scout"
      build build-asan "${ASAN_CI_TARGETS[@]}"
    else
      # Each test program started once per shard rather than once per test (the subset has no
      # RUN_SERIAL test): scripts/sanitizers/run_grouped.py says why.
      local costs=()
      [[ -f build/Testing/Temporary/CTestCostData.txt ]] && costs=(--costs build/Testing/Temporary/CTestCostData.txt)
      local tools_regex
      tools_regex="^($(IFS='|'; echo "${ASAN_CI_TOOLS_TESTS[*]//./\\.}"))\$"
      require_tests build "${ASAN_CI_TOOLS_TESTS[@]/#/^}"
      with_sanitizer_logs build-asan "$supp/lsan.supp" asan_ci_tests "$tools_regex" "${costs[@]}"
    fi
    what="the labelled subset (scripts/sanitize.sh)"
  else
    if [[ "$1" == build ]]; then
      configure build-asan address,undefined -DSCOUT_PYTHON_REFERENCE_PROGRAM=
      build build-asan
    else
      with_sanitizer_logs build-asan "$supp/lsan.supp" ctest --test-dir build-asan --output-on-failure -j"$jobs"
    fi
    what="the whole suite"
  fi
  echo "sanitize: AddressSanitizer + UndefinedBehaviorSanitizer: $1 of $what done in $((SECONDS - start)) s"
}

# The TSan tests: the threaded libraries' from this tree, then the multi-process ones from the
# Release build's tools_process_tests against this tree's `scout`; both run whatever the other's
# result.
tsan_tests() {  # regex
  local status=0
  # shellcheck disable=SC2046  # junit's option and its path, split on purpose
  "${no_aslr[@]}" ctest --test-dir build-tsan --output-on-failure --no-tests=error -R "$1" $(junit tsan) || status=$?
  # shellcheck disable=SC2046
  SCOUT_TEST_PROGRAM="$PWD/build-tsan/tools/scout" "${no_aslr[@]}" ctest --test-dir build --output-on-failure \
    --no-tests=error -L tools -R "$1" $(junit tsan-processes) || status=$?
  return "$status"
}

thread() {  # build|test
  local start=$SECONDS
  if [[ "$1" == build ]]; then
    if [[ -z "$step" ]]; then  # the multi-process tests' programs (in a step of .ci/run: built)
      cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
      build build tools_process_tests
    fi
    configure build-tsan thread
    build build-tsan "${TSAN_TARGETS[@]}"
  else
    # TSan maps its shadow memory at fixed addresses, which the kernel's address-space layout
    # randomisation can collide with (Linux 6.x with 32 random mmap bits): run without it where
    # the kernel lets us.
    local no_aslr=()
    if setarch "$(uname -m)" -R true 2>/dev/null; then no_aslr=(setarch "$(uname -m)" -R); fi
    # One test at a time: the multi-process tests bound how long the survivors take to stop after a
    # lost rank, and two of them at once under TSan's slowdown would be timing the machine (the
    # others take seconds).
    local tests=$TSAN_TESTS
    [[ "$which" == ci ]] && tests=$TSAN_CI_TESTS
    require_tests build-tsan "${TSAN_FAMILIES[@]}"
    require_tests build "${TSAN_CI_NAMED[@]}"
    with_sanitizer_logs build-tsan "$supp/tsan.supp" tsan_tests "$tests"
  fi
  echo "sanitize: ThreadSanitizer: $1 of the worker pool, physics, camera, environment and multi-process tests done in $((SECONDS - start)) s"
}

if [[ -n "$step" ]]; then
  ${step#*-} "${step%-*}"
else
  # Separate statements, not `build && test`: bash ignores errexit inside a function called on
  # the left of &&, so a failed build would go unnoticed.
  if [[ "$which" == address || "$which" == all || "$which" == ci ]]; then
    address build
    address test
  fi
  if [[ "$which" == thread || "$which" == all || "$which" == ci ]]; then
    thread build
    thread test
  fi
fi
