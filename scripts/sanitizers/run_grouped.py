#!/usr/bin/python3
"""Runs the tests that `ctest` would run, but each GoogleTest program once per shard (up to two
per core, each with its share of the tests: GoogleTest's sharding) instead of once per test.

    run_grouped.py BUILD_FOLDER JOBS [--costs FILE] [ctest selection: -L, -E, -R ...]

Why: under AddressSanitizer a test program that links LibTorch takes about 2.5 s to start, and
ctest starts one process per test, so the sanitizer pass spent a third of its test time starting
programs. Tests that are not GoogleTest programs (the Python tests) run through ctest itself, with
the environment ctest gives them. Every test still runs, in the program, folder and environment
ctest would use; a failing program's output is printed whole, and the exit status is 1, as it is
when a program runs fewer tests than it was given.

Each program is split into up to two shards per core, and the longest runs start first, by the
tests' times in ctest's cost data (--costs: another build's CTestCostData.txt, e.g. the Release
build's; else this folder's; else every test counts the same).
"""
import os
import re
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

# A generous bound on one shard, so that a hang ends the run instead of CI's time.
SHARD_TIMEOUT_S = 1800


def listed_tests(folder, selection):
    """The selected tests as ctest lists them: (number, name, command, working folder, environment:
    the variables the test's ENVIRONMENT property sets, as a sorted tuple of NAME=VALUE)."""
    out = subprocess.run(["ctest", "--test-dir", folder, "-N", "-V", *selection], check=True,
                         capture_output=True, text=True).stdout
    commands, folders, environments, tests = {}, {}, {}, []
    in_environment = None
    for line in out.splitlines():
        if m := re.match(r"^(\d+): Test command: (.*)$", line):
            commands[int(m[1])] = m[2]
        elif m := re.match(r"^(\d+): Working Directory: (.*)$", line):
            folders[int(m[1])] = m[2]
        elif m := re.match(r"^(\d+): Environment variables:", line):
            in_environment = int(m[1])
            environments[in_environment] = []
        elif (m := re.match(r"^(\d+):  (\S+?=.*)$", line)) and int(m[1]) == in_environment:
            environments[in_environment].append(m[2])
        elif m := re.match(r"^\s*Test\s+#(\d+): (\S+)", line):
            n = int(m[1])
            in_environment = None
            tests.append((n, m[2], commands[n], folders.get(n, folder), tuple(sorted(environments.get(n, [])))))
    return tests


def read_costs(paths):
    """ctest's cost data (lines "name runs seconds"), from the first of the files that exists."""
    for path in paths:
        if os.path.exists(path):
            costs = {}
            with open(path) as f:
                for line in f:
                    parts = line.split()
                    if len(parts) == 3:
                        costs[parts[0]] = float(parts[2])
            return costs
    return {}


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    folder, jobs, selection = os.path.abspath(sys.argv[1]), int(sys.argv[2]), sys.argv[3:]
    cost_files = [os.path.join(folder, "Testing", "Temporary", "CTestCostData.txt")]
    if selection[:1] == ["--costs"]:
        cost_files.insert(0, selection[1])
        selection = selection[2:]
    if not os.path.exists(os.path.join(folder, "CTestTestfile.cmake")):
        sys.exit(f"run_grouped: {folder}: not a configured build folder (no CTestTestfile.cmake)")
    costs = read_costs(cost_files)
    start = time.monotonic()
    # (program, folder, environment) -> gtest names: a program that ctest runs with two environments
    # (the camera's tests, once per back end) runs once per environment here too.
    programs = {}
    program_costs = {}
    others = []  # ctest names of tests that are not GoogleTest programs
    for _, name, command, cwd, environment in listed_tests(folder, selection):
        m = re.match(r'^(\S+) "--gtest_filter=([^"]+)"', command)
        if m:
            key = (m[1], cwd, environment)
            programs.setdefault(key, []).append(m[2])
            program_costs[key] = program_costs.get(key, 0.0) + costs.get(name, 1.0)
        else:
            others.append(name)
    if not programs and not others:
        sys.exit(f"run_grouped: no test in {folder} matches {' '.join(selection)}")

    runs = []  # (expected cost, label, argv, cwd, environment, tests it must run)
    for (program, cwd, environment), names in programs.items():
        shards = min(2 * jobs, len(names))
        for index in range(shards):
            env = dict(os.environ, GTEST_TOTAL_SHARDS=str(shards), GTEST_SHARD_INDEX=str(index))
            env.update(entry.split("=", 1) for entry in environment)
            shown = f" ({' '.join(environment)})" if environment else ""
            runs.append((program_costs[(program, cwd, environment)] / shards,
                         f"{os.path.basename(program)}{shown} shard {index + 1}/{shards} of {len(names)} tests",
                         [program, "--gtest_filter=" + ":".join(names), "--gtest_also_run_disabled_tests"], cwd, env,
                         len(range(index, len(names), shards))))
    for name in others:
        runs.append((costs.get(name, 1.0), name,
                     ["ctest", "--test-dir", folder, "--output-on-failure", "-R", f"^{re.escape(name)}$"], folder,
                     dict(os.environ), None))
    runs.sort(key=lambda r: -r[0])

    def run(item):
        _, label, argv, cwd, env, expected = item
        began = time.monotonic()
        with tempfile.TemporaryFile(mode="w+") as log:
            try:
                status = subprocess.run(argv, cwd=cwd, env=env, stdout=log, stderr=subprocess.STDOUT,
                                        timeout=SHARD_TIMEOUT_S).returncode
            except subprocess.TimeoutExpired:
                status = f"timed out after {SHARD_TIMEOUT_S} s"
            log.seek(0)
            output = log.read()
        if status == 0 and expected is not None:
            # GoogleTest's own count: a filter that matched less than it should is a failure too.
            ran = re.search(r"^\[==========\] (\d+) tests? from .* ran\.", output, re.M)
            if not ran or int(ran[1]) != expected:
                status = f"ran {ran[1] if ran else 'no'} tests of {expected}"
        return label, status, time.monotonic() - began, output

    failed = []
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        for label, status, seconds, output in pool.map(run, runs):
            verdict = "passed" if status == 0 else f"FAILED ({status})"
            print(f"run_grouped: {label}: {verdict} in {seconds:.0f} s", flush=True)
            if status != 0:
                failed.append(label)
                print(output, flush=True)
    count = sum(len(names) for names in programs.values()) + len(others)
    elapsed = time.monotonic() - start
    if failed:
        print(f"run_grouped: {len(failed)} of {len(runs)} runs failed ({', '.join(failed)}) in {elapsed:.0f} s")
        sys.exit(1)
    print(f"run_grouped: {count} tests in {len(runs)} runs passed in {elapsed:.0f} s")


if __name__ == "__main__":
    main()
