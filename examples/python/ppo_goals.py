#!/usr/bin/env python3
"""PPO in plain PyTorch on Scout through Gymnasium: learning where to drive for a fixed classifier.

The environment is Gymnasium's own: `gymnasium.make_vec("scout/MNIST-v0", ...)` on the training
digits, with SAME_STEP autoreset, `RecordEpisodeStatistics` (the runs' returns) and
`NormalizeReward` (what PPO learns from). The classifier is fixed: scout.Agent's (models/mnist.safetensors),
asked at every move for its log-probabilities on what the robot has revealed so far, which the
action carries as its `prediction`; the dense reward is then log p(label), so a run's return is
higher the sooner the robot shows the classifier what it needs. An actor-critic (a small CNN over
the revealed floor, the seen mask, the robot's cell and the time) picks the moves, and learns them
by PPO (clipped ratio, GAE, value loss, entropy bonus).

It then scores the learned moves and uniform random moves on the same held-out runs (the MNIST
test digits, the same starts): the classifier's accuracy after the run's 20 moves and its mean
log p(label). Optionally it draws the training curve.

    PYTHONPATH=build/python .venv/bin/python examples/python/ppo_goals.py \
        [--seconds 120 | --updates N] [--plot curve.png]
"""
import argparse
import os
import sys
import time

import numpy as np
import torch
from torch import nn

import gymnasium
from gymnasium.vector import AutoresetMode

import scout

SOURCE = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MOVES = 4


def planes(obs, moves_per_run):
    """(N, 4, H, W): the revealed floor, the seen mask, the robot's cell, the share of the run done."""
    n, h, w = obs["seen"].shape
    here = np.zeros((n, h, w), np.float32)
    here[np.arange(n), obs["pose"][:, 1], obs["pose"][:, 0]] = 1.0
    done = np.broadcast_to((obs["time_step"] / moves_per_run).astype(np.float32)[:, None, None], (n, h, w))
    return torch.from_numpy(np.stack([obs["revealed"], obs["seen"].astype(np.float32), here, done], axis=1))


class ActorCritic(nn.Module):
    """Planes -> move logits (4) and the value of the state."""

    def __init__(self, height, width):
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(4, 16, 3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(16, 32, 3, stride=2, padding=1), nn.ReLU(), nn.Flatten(),
            nn.Linear(32 * ((height + 3) // 4) * ((width + 3) // 4), 128), nn.ReLU())
        self.actor = nn.Linear(128, MOVES)
        self.critic = nn.Linear(128, 1)
        nn.init.zeros_(self.actor.weight)  # start from uniform moves
        nn.init.zeros_(self.actor.bias)

    def forward(self, x):
        h = self.body(x)
        return self.actor(h), self.critic(h).squeeze(1)


def make_envs(num_envs, seed):
    envs = gymnasium.make_vec("scout/MNIST-v0", num_envs=num_envs, split="train", seed=seed,
                              autoreset_mode=AutoresetMode.SAME_STEP)
    envs = gymnasium.wrappers.vector.RecordEpisodeStatistics(envs)
    return gymnasium.wrappers.vector.NormalizeReward(envs, gamma=0.99)


def rollout(envs, obs, net, classifier, run, rng):
    """One run of every robot (they start and end together), moves sampled from `net` (uniform
    random moves without one). Returns the transitions, the next observation, the runs' raw
    returns (RecordEpisodeStatistics') and whether the classifier was right after each."""
    steps = {"x": [], "move": [], "log_p": [], "value": [], "reward": [], "end": []}
    returns, right = [], []
    for _ in range(run):
        state = planes(obs, run)
        if net is None:
            move = torch.from_numpy(rng.integers(0, MOVES, len(state)))
        else:
            with torch.no_grad():
                logits, value = net(state)
            dist = torch.distributions.Categorical(logits=logits)
            move = dist.sample()
            for key, item in (("x", state), ("move", move), ("log_p", dist.log_prob(move)), ("value", value)):
                steps[key].append(item)
        obs, reward, terminated, truncated, info = envs.step(
            {"move": move.numpy(), "prediction": classifier.classify(obs)})
        steps["reward"].append(torch.as_tensor(reward, dtype=torch.float32))
        steps["end"].append(torch.as_tensor(terminated | truncated, dtype=torch.float32))
        if "episode" in info:
            returns.extend(info["episode"]["r"][info["_episode"]])
        if "final_obs" in info:  # SAME_STEP: the run's last observation, before the next run began
            done = np.flatnonzero(info["_final_obs"])
            final = {k: np.stack([info["final_obs"][i][k] for i in done]) for k in ("pose", "seen", "revealed", "patch")}
            right.extend(classifier.classify(final).argmax(1) == info["final_info"]["label"][done])
    return steps, obs, returns, right


def train(args, classifier):
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    envs = make_envs(args.num_envs, args.seed)
    run = envs.unwrapped.episodes * envs.unwrapped.steps  # E x T moves
    height, width = envs.single_observation_space["seen"].shape
    net = ActorCritic(height, width)
    optimizer = torch.optim.Adam(net.parameters(), lr=args.lr)
    obs, _ = envs.reset(seed=args.seed)
    # Random moves on the same kind of runs first: the curve's baseline.
    baseline_returns, baseline_right = [], []
    for _ in range(args.baseline_updates):
        _, obs, returns, right = rollout(envs, obs, None, classifier, run, rng)
        baseline_returns += returns
        baseline_right += right
    baseline = (float(np.mean(baseline_returns)), float(np.mean(baseline_right)))
    n = args.num_envs
    curve = []  # (seconds, runs so far, mean raw return, accuracy at the runs' end)
    start, runs = time.perf_counter(), 0
    while (len(curve) < args.updates) if args.updates else (time.perf_counter() - start < args.seconds):
        steps, obs, returns, right = rollout(envs, obs, net, classifier, run, rng)
        values, rewards, ends = steps["value"], steps["reward"], steps["end"]
        # GAE over the rollout; a state after a run's end has no value to bootstrap from.
        with torch.no_grad():
            next_value = net(planes(obs, run))[1]
        advantages, gae = [], torch.zeros(n)
        for t in reversed(range(run)):
            following = next_value if t == run - 1 else values[t + 1]
            delta = rewards[t] + args.gamma * following * (1 - ends[t]) - values[t]
            gae = delta + args.gamma * args.lam * (1 - ends[t]) * gae
            advantages.insert(0, gae)
        x, moves, old_log_p = torch.cat(steps["x"]), torch.cat(steps["move"]), torch.cat(steps["log_p"])
        advantages = torch.cat(advantages)
        targets = advantages + torch.cat(values)
        for _ in range(args.epochs):
            for batch in torch.randperm(len(x)).split(len(x) // args.minibatches):
                logits, value = net(x[batch])
                dist = torch.distributions.Categorical(logits=logits)
                ratio = torch.exp(dist.log_prob(moves[batch]) - old_log_p[batch])
                adv = advantages[batch]
                adv = (adv - adv.mean()) / (adv.std() + 1e-8)
                policy_loss = -torch.min(ratio * adv, torch.clamp(ratio, 1 - args.clip, 1 + args.clip) * adv).mean()
                value_loss = 0.5 * ((value - targets[batch]) ** 2).mean()
                loss = policy_loss + 0.5 * value_loss - args.entropy * dist.entropy().mean()
                optimizer.zero_grad()
                loss.backward()
                nn.utils.clip_grad_norm_(net.parameters(), 0.5)
                optimizer.step()
        runs += len(returns)
        curve.append((time.perf_counter() - start, runs, float(np.mean(returns)), float(np.mean(right))))
        if len(curve) % 10 == 1:
            print(f"{curve[-1][0]:6.0f} s  {runs:6d} runs  return {curve[-1][2]:7.2f}  accuracy {100 * curve[-1][3]:5.1f} %",
                  flush=True)
    envs.close()
    return net, curve, baseline


@torch.no_grad()
def score(net, classifier, args, rng):
    """Accuracy and mean log p(label) after a run, over the same held-out runs (moves by `net`, or
    uniform random moves without one)."""
    envs = scout.make_vec(os.path.join(SOURCE, "worlds", "mnist.yaml"), args.num_envs, seed=args.seed + 1000,
                          split="test")
    run = envs.episodes * envs.steps
    right, log_p_label, total = 0, 0.0, 0
    while total < args.eval_runs:
        obs, info = envs.reset()
        for _ in range(run):
            if net is None:
                move = rng.integers(0, MOVES, envs.num_envs)
            else:
                move = torch.distributions.Categorical(logits=net(planes(obs, run))[0]).sample().numpy()
            obs, *_ = envs.step({"move": move})
        log_p = classifier.classify(obs)
        right += int((log_p.argmax(1) == info["label"]).sum())
        log_p_label += float(log_p[np.arange(envs.num_envs), info["label"]].sum())
        total += envs.num_envs
    return right / total, log_p_label / total


def plot(curve, random_accuracy, random_return, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    seconds, _, returns, accuracy = (np.array(c) for c in zip(*curve))
    smooth = lambda y: np.convolve(y, np.ones(5) / 5, mode="valid")  # noqa: E731
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.6))
    left.plot(seconds[4:], smooth(returns), label="PPO (training runs, mean of 5 updates)")
    left.axhline(random_return, color="grey", linestyle="--", label="random moves (training runs)")
    left.set(xlabel="training time (s)", ylabel="return of a run (sum of log p(label))")
    left.legend()
    right.plot(seconds[4:], 100 * smooth(accuracy), label="PPO (training runs, mean of 5 updates)")
    right.axhline(100 * random_accuracy, color="grey", linestyle="--", label="random moves (training runs)")
    right.set(xlabel="training time (s)", ylabel="classifier accuracy after 20 moves (%)")
    right.legend()
    fig.suptitle("PPO on gymnasium.make_vec(\"scout/MNIST-v0\", num_envs=64), fixed classifier (models/mnist.safetensors)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120, help="training time")
    parser.add_argument("--updates", type=int, help="train this many PPO updates instead (the same on any machine)")
    parser.add_argument("--model", default=os.path.join(SOURCE, "models", "mnist.safetensors"), help="the fixed classifier")
    parser.add_argument("--num-envs", type=int, default=64)
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--gamma", type=float, default=0.99)
    parser.add_argument("--lam", type=float, default=0.95)
    parser.add_argument("--clip", type=float, default=0.2)
    parser.add_argument("--entropy", type=float, default=0.01)
    parser.add_argument("--epochs", type=int, default=4)
    parser.add_argument("--minibatches", type=int, default=4)
    parser.add_argument("--eval-runs", type=int, default=2048, help="held-out runs per scoring")
    parser.add_argument("--baseline-updates", type=int, default=8, help="rollouts of random moves for the curve's baseline")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--threads", type=int, default=1,
                        help="PyTorch's and the classifier's threads (1: the steadiest on a shared 2-core machine)")
    parser.add_argument("--plot", help="write the training curve here (PNG)")
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    classifier = scout.Agent(args.model, threads=args.threads, precision="fp32")
    net, curve, baseline = train(args, classifier)
    learned_accuracy, learned_log_p = score(net, classifier, args, np.random.default_rng(args.seed))
    random_accuracy, random_log_p = score(None, classifier, args, np.random.default_rng(args.seed))
    print(f"trained {curve[-1][1]} runs ({len(curve)} PPO updates of {args.num_envs} robots) in {curve[-1][0]:.0f} s; "
          f"training runs' return {curve[-1][2]:.2f} (random moves {baseline[0]:.2f})")
    print(f"held-out accuracy after 20 moves: learned moves {100 * learned_accuracy:.1f} %, random moves "
          f"{100 * random_accuracy:.1f} % (gain {100 * (learned_accuracy - random_accuracy):.1f} points); "
          f"mean log p(label) {learned_log_p:.3f} vs {random_log_p:.3f}")
    if args.plot:
        plot(curve, baseline[1], baseline[0], args.plot)
        print(f"curve: {args.plot}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
