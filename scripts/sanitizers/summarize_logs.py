#!/usr/bin/python3
"""Reads the sanitizer logs of one pass and says what they hold.

    summarize_logs.py LOG_FOLDER SUPPRESSION_FILE...

scripts/sanitize.sh points the sanitizers' `log_path` into LOG_FOLDER, so every process of the
pass — each test program, each `scout` it starts, each rank of a multi-process run, each forked
child, the Python interpreter — writes what its sanitizer prints to a file of its own
(LOG_FOLDER/<sanitizer>.<pid>), whoever reads or ignores that process's stderr. This script:

  - prints every suppression that matched, with the number of processes and of matches (and of
    leaked bytes for LeakSanitizer), summed over the pass: what the suppression files hide is in
    the CI log;
  - names the suppressions of the given files that matched nothing in this pass;
  - prints every report (AddressSanitizer, LeakSanitizer, ThreadSanitizer, UndefinedBehavior-
    Sanitizer) whole and exits with status 1 if there is one, even where the process that found
    it exited with the status its test expected (a rank of a multi-process run, a forked child).
"""
import collections
import os
import re
import sys

# The first line of each kind of report the sanitizers write.
REPORT = re.compile(r"ERROR: (AddressSanitizer|LeakSanitizer)|WARNING: ThreadSanitizer|runtime error:")
# LeakSanitizer's table, after "Suppressions used:" and its header: "count bytes template".
LSAN_ROW = re.compile(r"^\s*(\d+)\s+(\d+)\s+(\S+)\s*$")
# ThreadSanitizer's, after "ThreadSanitizer: Matched N suppressions (pid=P):": "count kind:template".
TSAN_ROW = re.compile(r"^(\d+) (\w+):(.+)$")
# How much of each report file to print (a report is some tens of lines; a file can hold several).
MAX_REPORT_LINES = 400
MAX_REPORT_FILES = 8


def read_suppressions(paths):
    """(kind, template) of every suppression in the files, in order."""
    entries = []
    for path in paths:
        with open(path) as f:
            for line in f:
                line = line.strip()
                if line and not line.startswith("#") and ":" in line:
                    kind, template = line.split(":", 1)
                    entries.append((kind, template))
    return entries


def parse_matches(text):
    """[(kind, template, count, bytes)] of the matched-suppression tables in one log."""
    matches = []
    table = None
    for line in text.splitlines():
        if line.startswith("Suppressions used:"):
            table = "lsan"
            continue
        if line.startswith("ThreadSanitizer: Matched"):
            table = "tsan"
            continue
        if table == "lsan":
            if m := LSAN_ROW.match(line):
                matches.append(("leak", m[3], int(m[1]), int(m[2])))
            elif not line.strip().startswith("count"):
                table = None
        elif table == "tsan":
            if m := TSAN_ROW.match(line):
                matches.append((m[2], m[3], int(m[1]), 0))
            else:
                table = None
    return matches


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    folder = sys.argv[1]
    suppressions = read_suppressions(sys.argv[2:])
    logs = sorted(os.listdir(folder)) if os.path.isdir(folder) else []
    totals = collections.OrderedDict()  # (kind, template) -> [processes, count, bytes]
    reports = []
    for name in logs:
        with open(os.path.join(folder, name), errors="replace") as f:
            text = f.read()
        for kind, template, count, size in parse_matches(text):
            row = totals.setdefault((kind, template), [0, 0, 0])
            row[0] += 1
            row[1] += count
            row[2] += size
        if REPORT.search(text):
            reports.append((name, text))

    print(f"sanitize: {len(logs)} processes wrote sanitizer logs to {folder}")
    if totals:
        print("sanitize: matched suppressions (processes, matches, leaked bytes):")
        for (kind, template), (processes, count, size) in sorted(totals.items(), key=lambda kv: -kv[1][1]):
            leaked = f"{size:>12,}" if kind == "leak" else f"{'-':>12}"
            print(f"  {processes:>6} {count:>8} {leaked}  {kind}:{template}")
    else:
        print("sanitize: no suppression matched")
    unused = [f"{kind}:{template}" for kind, template in suppressions if (kind, template) not in totals]
    if unused:
        print("sanitize: suppressions that matched nothing in this pass: " + ", ".join(unused))

    if reports:
        print(f"sanitize: {len(reports)} processes reported errors; the first {min(len(reports), MAX_REPORT_FILES)}:")
        for name, text in reports[:MAX_REPORT_FILES]:
            lines = text.splitlines()
            print(f"----- {name} ({len(lines)} lines) -----")
            print("\n".join(lines[:MAX_REPORT_LINES]))
        return 1
    print("sanitize: no sanitizer report")
    return 0


if __name__ == "__main__":
    sys.exit(main())
