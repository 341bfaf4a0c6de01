#!/usr/bin/env python3
"""A random agent on Scout's default world: every robot makes i.i.d. moves and the prediction is
uniform, so the reward is log(1/10) at every move. Prints what a run looks like and how fast the
environment steps.

    PYTHONPATH=build/python .venv/bin/python examples/python/random_agent.py [--num-envs 240]
"""
import argparse
import os
import time

import numpy as np

import scout

SOURCE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default=os.path.join(SOURCE, "worlds", "mnist.yaml"))
    parser.add_argument("--num-envs", type=int, default=240)
    parser.add_argument("--runs", type=int, default=3, help="runs per robot")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)

    envs = scout.make_vec(args.world, args.num_envs, seed=args.seed)
    envs.action_space.seed(args.seed)
    obs, info = envs.reset()
    uniform = np.zeros((envs.num_envs, envs.num_classes), np.float32)
    steps = args.runs * envs.episodes * envs.steps
    total_reward, revealed = 0.0, []
    start = time.perf_counter()
    for _ in range(steps):
        action = {"move": envs.action_space["move"].sample(), "prediction": uniform}
        obs, reward, terminated, truncated, info = envs.step(action)
        total_reward += float(reward.sum())
        if terminated.any():
            revealed.append(obs["seen"][terminated].mean())
    seconds = time.perf_counter() - start
    print(f"{envs.num_envs} robots x {steps} moves in {seconds:.2f} s: "
          f"{envs.num_envs * steps / seconds:,.0f} agent-steps/s")
    print(f"mean reward per move {total_reward / (envs.num_envs * steps):.4f} (log 1/10 = {np.log(0.1):.4f}); "
          f"random moves reveal {100 * np.mean(revealed):.1f} % of the floor by the end of a run")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
