#!/usr/bin/python3
"""Prints where CI's time went: each step's wall time (from .ci/run's STEPS file, lines
"seconds<TAB>step"), then the slowest tests by ctest's own timings (its JUnit files, one per ctest
call, named after the pass that ran them).

    time_table.py STEPS_FILE TOTAL_SECONDS [JUNIT.xml ...]
"""
import os
import sys
import xml.etree.ElementTree as ElementTree

SLOWEST = 15


def main():
    steps_file, total, junit_files = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
    print(f"\nci: time table ({total} s in all)")
    print(f"  {'seconds':>7}  step")
    with open(steps_file) as f:
        for line in f:
            seconds, step = line.rstrip("\n").split("\t", 1)
            print(f"  {int(seconds):>7}  {step}")
    tests = []
    for path in junit_files:
        if not os.path.exists(path):
            continue
        try:
            root = ElementTree.parse(path).getroot()
        except ElementTree.ParseError:
            continue
        pass_name = os.path.basename(path).removesuffix(".xml")
        for case in root.iter("testcase"):
            tests.append((float(case.get("time", 0)), case.get("name", "?"), pass_name))
    if tests:
        tests.sort(reverse=True)
        print(f"ci: the {min(SLOWEST, len(tests))} slowest tests (ctest's timings, of {len(tests)} runs)")
        for seconds, name, pass_name in tests[:SLOWEST]:
            print(f"  {seconds:>7.1f}  {name}  [{pass_name}]")


if __name__ == "__main__":
    main()
