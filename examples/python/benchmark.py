#!/usr/bin/python3
"""How fast Scout steps from Python: 240 robots making random moves, the same move stream once
through the Python API (`envs.step`, new NumPy arrays every step) and once through the C++ step
API (env::VectorEnv, one set of arrays, no Python in the loop), medians of repeated rounds.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/benchmark.py [--robots 240] [--json FILE]
"""
import argparse
import json
import os
import platform
import statistics
import time

import numpy as np

import scout

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
    parser.add_argument("--json", help="also write the figures here")
    args = parser.parse_args(argv)

    moves = np.random.default_rng(1).integers(0, 4, (args.steps, args.robots)).astype(np.int32)
    python_s, cpp_s = [], []
    for _ in range(args.rounds):
        for name, times in (("python", python_s), ("c++", cpp_s)):
            envs = scout.make_vec(args.world, args.robots, seed=3)
            envs.reset()
            if name == "python":
                start = time.perf_counter()
                for t in range(args.steps):
                    envs.step({"move": moves[t]})
                times.append(time.perf_counter() - start)
            else:
                times.append(envs._core.bench(moves))
    steps = args.robots * args.steps
    python_rate, cpp_rate = steps / statistics.median(python_s), steps / statistics.median(cpp_s)
    print(f"{cpu()}; {args.robots} robots, {args.steps} random moves, median of {args.rounds} rounds")
    print(f"  Python envs.step      {python_rate:>12,.0f} agent-steps/s")
    print(f"  C++ env::VectorEnv    {cpp_rate:>12,.0f} agent-steps/s")
    print(f"  Python / C++          {100 * python_rate / cpp_rate:>11.1f} %  (target >= 70 %)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"cpu": cpu(), "robots": args.robots, "steps": args.steps, "rounds": args.rounds,
                       "python_agent_steps_per_s": python_rate, "cpp_agent_steps_per_s": cpp_rate,
                       "ratio": python_rate / cpp_rate}, f, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
