#!/usr/bin/env python3
"""How fast Scout steps from Python: 240 robots making random moves, the same move stream through
the C++ step API (env::VectorEnv, one set of arrays, no Python in the loop), through the Python
API (`envs.step` of make_vec's environment, new NumPy arrays every step: a
gymnasium.vector.VectorEnv where Gymnasium imports) and, where Gymnasium imports, through
gymnasium.wrappers.vector.RecordEpisodeStatistics around it; medians of repeated rounds.

    PYTHONPATH=build/python .venv/bin/python examples/python/benchmark.py \
        [--robots 240] [--json FILE]
"""
import argparse
import json
import os
import platform
import statistics
import time

import numpy as np

import scout

try:
    import gymnasium
except ImportError:  # the package's own environment only
    gymnasium = None

SOURCE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def cpu():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default=os.path.join(SOURCE, "worlds", "mnist.yaml"))
    parser.add_argument("--robots", type=int, default=240)
    parser.add_argument("--steps", type=int, default=200, help="steps per round")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                        help="cpu: the process's CPU time, steadier than wall time on a machine others load")
    parser.add_argument("--json", help="also write the figures here")
    args = parser.parse_args(argv)

    moves = np.random.default_rng(1).integers(0, 4, (args.steps, args.robots)).astype(np.int32)
    kinds = ["c++", "python"] + (["record"] if gymnasium else [])
    times = {kind: [] for kind in kinds}
    for _ in range(args.rounds):
        for kind in kinds:
            envs = scout.make_vec(args.world, args.robots, seed=3)
            if kind == "record":
                envs = gymnasium.wrappers.vector.RecordEpisodeStatistics(envs)
            envs.reset()
            clock = time.process_time if args.clock == "cpu" else time.perf_counter
            start = clock()
            if kind == "c++":
                seconds = envs._core.bench(moves)
                times[kind].append(clock() - start if args.clock == "cpu" else seconds)
                continue
            for t in range(args.steps):
                envs.step({"move": moves[t]})
            times[kind].append(clock() - start)
    steps = args.robots * args.steps
    rate = {kind: steps / statistics.median(times[kind]) for kind in kinds}
    kind_of_env = "a Gymnasium VectorEnv" if gymnasium else "no Gymnasium"
    print(f"{cpu()}; {args.robots} robots, {args.steps} random moves, median of {args.rounds} rounds "
          f"({args.clock} clock)")
    print(f"  {'C++ env::VectorEnv':<46}{rate['c++']:>10,.0f} agent-steps/s")
    print(f"  {'Python envs.step (' + kind_of_env + ')':<46}{rate['python']:>10,.0f} agent-steps/s "
          f"{100 * rate['python'] / rate['c++']:6.1f} % of C++  (target >= 85 %)")
    if gymnasium:
        print(f"  {'RecordEpisodeStatistics(envs).step':<46}{rate['record']:>10,.0f} agent-steps/s "
              f"{100 * rate['record'] / rate['c++']:6.1f} % of C++  (target >= 80 %)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"cpu": cpu(), "clock": args.clock, "robots": args.robots, "steps": args.steps, "rounds": args.rounds,
                       "gymnasium": gymnasium is not None,
                       "cpp_agent_steps_per_s": rate["c++"], "python_agent_steps_per_s": rate["python"],
                       "ratio": rate["python"] / rate["c++"],
                       "record_agent_steps_per_s": rate.get("record"),
                       "record_ratio": rate["record"] / rate["c++"] if gymnasium else None}, f, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
