#!/usr/bin/env python3
"""REINFORCE in PyTorch on Scout's robots: floors whose class can be read only in one corner.

The example writes its own data set (12 x 12 floors of noise whose top-left 3 x 3 block is black
for class 0 and white for class 1; fixed seeds; train, validation and a held-out test split) and a
world file for it (m = 3, two episodes of five 2-px moves, random start). One small network looks
at what a robot has revealed, what it has seen and where it is, and gives both the next move and
the class. It learns the moves by REINFORCE, rewarded by the log-probability its classifier gives
the right class after the last move, and the classifier by cross-entropy. For comparison, the
same network learns to classify with i.i.d. moves for the same number of batches. Both are scored
on the held-out floors.

    PYTHONPATH=build/python .venv/bin/python examples/python/reinforce_corner.py [--seconds 120]
"""
import argparse
import os
import struct
import sys
import tempfile
import time

import numpy as np
import torch
from torch import nn

import scout

SIDE, BLOCK = 12, 3


def corner_floors(count, rng):
    images = rng.integers(64, 192, (count, SIDE, SIDE), dtype=np.uint8)
    labels = rng.integers(0, 2, count).astype(np.uint8)
    images[:, :BLOCK, :BLOCK] = np.where(labels[:, None, None] == 1, 255, 0).astype(np.uint8)
    return images, labels


def write_idx(folder, prefix, images, labels):
    with open(os.path.join(folder, f"{prefix}-images-idx3-ubyte"), "wb") as f:
        f.write(struct.pack(">IIII", 0x803, len(images), SIDE, SIDE))
        f.write(images.tobytes())
    with open(os.path.join(folder, f"{prefix}-labels-idx1-ubyte"), "wb") as f:
        f.write(struct.pack(">II", 0x801, len(labels)))
        f.write(labels.tobytes())


def make_world(folder, seed):
    rng = np.random.default_rng(seed)
    for prefix, count in (("train", 4000), ("validation", 500), ("t10k", 1000)):
        write_idx(folder, prefix, *corner_floors(count, rng))
    world = os.path.join(folder, "corner.yaml")
    with open(world, "w") as f:
        f.write(f"floor: {{dataset: {folder}, split: train, index: random}}\n"
                "camera: {patch_px: 3}\n"
                "task: {episodes: 2, steps: 5, step_px: 2}\n"
                f"seed: {seed}\n")
    return world


class Net(nn.Module):
    """Planes (revealed floor, seen mask, the robot's cell) -> move logits (4) and class logits (2)."""

    def __init__(self):
        super().__init__()
        self.body = nn.Sequential(nn.Conv2d(3, 16, 3, padding=1), nn.ReLU(), nn.Conv2d(16, 16, 3, padding=1),
                                  nn.ReLU(), nn.Flatten())
        self.move = nn.Linear(16 * SIDE * SIDE, 4)
        self.classify = nn.Linear(16 * SIDE * SIDE, 2)

    def forward(self, obs):
        n = obs["pose"].shape[0]
        here = np.zeros((n, SIDE, SIDE), np.float32)
        here[np.arange(n), obs["pose"][:, 1], obs["pose"][:, 0]] = 1.0
        x = torch.from_numpy(np.stack([obs["revealed"], obs["seen"].astype(np.float32), here], axis=1))
        h = self.body(x)
        return self.move(h), self.classify(h)


def run_batch(envs, net, learned_moves, rng):
    """One run of every robot; returns the moves' summed log-probabilities and the class logits."""
    obs, info = envs.reset()
    log_pi = torch.zeros(envs.num_envs)
    for _ in range(envs.episodes * envs.steps):
        move_logits, _ = net(obs)
        if learned_moves:
            dist = torch.distributions.Categorical(logits=move_logits)
            move = dist.sample()
            log_pi = log_pi + dist.log_prob(move)
            move = move.numpy()
        else:
            move = rng.integers(0, 4, envs.num_envs)
        obs, reward, terminated, truncated, _ = envs.step({"move": move})
    assert terminated.all()
    _, class_logits = net(obs)
    return log_pi, class_logits, torch.from_numpy(info["label"].astype(np.int64))


def train(world, learned_moves, batches, seconds, num_envs, seed):
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = Net()
    optimizer = torch.optim.Adam(net.parameters(), lr=3e-3)
    envs = scout.make_vec(world, num_envs, seed=seed, split="train")
    done, start = 0, time.perf_counter()
    while (batches is None and time.perf_counter() - start < seconds) or (batches is not None and done < batches):
        log_pi, class_logits, labels = run_batch(envs, net, learned_moves, rng)
        log_p_label = torch.log_softmax(class_logits, 1)[torch.arange(len(labels)), labels]
        loss = -log_p_label.mean()
        if learned_moves:  # REINFORCE with the batch's mean reward as baseline
            reward = log_p_label.detach()
            loss = loss - ((reward - reward.mean()) * log_pi).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        done += 1
    return net, done


@torch.no_grad()
def score(world, net, learned_moves, num_envs, seed, runs=1000):
    envs = scout.make_vec(world, num_envs, seed=seed + 1000, split="test")
    rng = np.random.default_rng(seed + 1000)
    right = total = 0
    while total < runs:
        _, class_logits, labels = run_batch(envs, net, learned_moves, rng)
        right += int((class_logits.argmax(1) == labels).sum())
        total += len(labels)
    return right / total


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=120, help="training time of the learned agent")
    parser.add_argument("--batches", type=int, help="train this many batches instead (the same on any machine)")
    parser.add_argument("--num-envs", type=int, default=128)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--threads", type=int, default=2, help="PyTorch threads")
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    with tempfile.TemporaryDirectory(prefix="scout-corner-") as folder:
        world = make_world(folder, args.seed)
        start = time.perf_counter()
        learned, batches = train(world, True, args.batches, args.seconds, args.num_envs, args.seed)
        trained_s = time.perf_counter() - start
        iid, _ = train(world, False, batches, None, args.num_envs, args.seed)
        learned_accuracy = score(world, learned, True, args.num_envs, args.seed)
        iid_accuracy = score(world, iid, False, args.num_envs, args.seed)
    print(f"trained {batches} batches of {args.num_envs} robots in {trained_s:.0f} s")
    print(f"held-out accuracy: learned moves {100 * learned_accuracy:.1f} %, i.i.d. moves {100 * iid_accuracy:.1f} % "
          f"(margin {100 * (learned_accuracy - iid_accuracy):.1f} points)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
