"""Scout against plain PyTorch, side by side in one run: training images/s of the paper's layered
agent in each mode, for Scout (`scout bench train`) and for a peer written the way a PyTorch user
would write it, eager and with torch.compile, in fp32 and in bf16 autocast.

The peer has Scout's networks exactly (agent/networks.cpp: dense stacks of 3 x 3 convolutions and
ReLU whose outputs are concatenated to their inputs, no normalisation; the planners' 1 x 1 heads;
the paper classifier whose block width doubles, a 1 x 1 head and global average pooling), the
paper's rollout (E x T = 4 x 5 moves of at most 2 px toward the goal, m = 6 patches, N = 4
rollouts of B = 60 images) on grid kinematics with exact pixel masks, Adam, and the unified reward's
loss. It has no physics and no renderer, which Scout has: it is the lower bound of what plain
PyTorch costs for the same arithmetic.

    .venv/bin/python benchmarks/pytorch_peer.py --scout build/tools/scout --rounds 3

prints one line per measurement and a table of medians (images/s, mode iii by default). Runs are
interleaved (Scout, peer eager, peer compiled, per precision, per round), so that a change in the
machine's load falls on all of them alike. `--json FILE` writes the table.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# .venv leaves out triton (torch.compile's GPU kernels: python/requirements.txt); on the CPU the
# compiler does not need it, and torch's warning that GPU flop counting will not work is noise here.
logging.getLogger("torch.utils.flop_counter").setLevel(logging.ERROR)
import torch  # noqa: E402
import torch.nn as nn  # noqa: E402

MODES = {"i": 1, "ii": 2, "iii": 3}


def read_idx_images(path: Path, count: int) -> torch.Tensor:
    raw = path.read_bytes()
    if int.from_bytes(raw[:4], "big") != 0x803:
        sys.exit(f"pytorch_peer: {path}: not an IDX image file (magic {raw[:4].hex()})")
    rows, cols = int.from_bytes(raw[8:12], "big"), int.from_bytes(raw[12:16], "big")
    pixels = np.frombuffer(raw, dtype=np.uint8, offset=16).reshape(-1, 1, rows, cols)[:count]
    return torch.from_numpy(pixels.astype(np.float32) / 255.0)


def read_idx_labels(path: Path, count: int) -> torch.Tensor:
    raw = path.read_bytes()
    if int.from_bytes(raw[:4], "big") != 0x801:
        sys.exit(f"pytorch_peer: {path}: not an IDX label file (magic {raw[:4].hex()})")
    return torch.from_numpy(np.frombuffer(raw, dtype=np.uint8, offset=8)[:count].astype(np.int64))


class DenseStack(nn.Module):
    """r blocks of conv 3 x 3 -> ReLU, each block's output concatenated to its input."""

    def __init__(self, channels: int, growth: int, depth: int, doubling: bool = False):
        super().__init__()
        self.convs = nn.ModuleList()
        for k in range(depth):
            width = growth << k if doubling else growth
            self.convs.append(nn.Conv2d(channels, width, 3, padding=1))
            channels += width
        self.out_channels = channels

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        for conv in self.convs:
            x = torch.cat([x, torch.relu(conv(x))], 1)
        return x


class Planner(nn.Module):
    def __init__(self, channels: int, width: int, depth: int, outputs: int):
        super().__init__()
        self.body = DenseStack(channels, width, depth)
        self.head = nn.Conv2d(self.body.out_channels, outputs, 1)

    def forward(self, u: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(u))


class Classifier(nn.Module):
    def __init__(self, channels: int, width: int, depth: int, classes: int):
        super().__init__()
        self.body = DenseStack(channels, width, depth, doubling=True)
        self.head = nn.Conv2d(self.body.out_channels, classes, 1)

    def forward(self, y: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(y)).mean((2, 3))


class Peer:
    """The three networks, their optimizer and one training step of the paper's rollout."""

    def __init__(self, args, compiled: bool, bf16: bool):
        c = 1
        self.goal = Planner(c + 3, args.planner_width, args.planner_depth, 1)
        self.action = Planner(c + 3, args.planner_width, args.planner_depth, 2)
        self.classifier = Classifier(c, args.classifier_width, args.classifier_depth, 10)
        modules = [self.goal, self.action, self.classifier]
        # bf16: the weights in channels-last, what oneDNN's bf16 kernels want (as Scout has them);
        # the inputs stay fp32 NCHW, as a PyTorch user writes them, and autocast casts them.
        if bf16:
            for m in modules:
                m.to(memory_format=torch.channels_last)
        self.optimizer = torch.optim.Adam([p for m in modules for p in m.parameters()], lr=1e-3)
        self.bf16 = bf16
        self.run_goal, self.run_action, self.run_classifier = (
            [torch.compile(m) for m in modules] if compiled else modules)
        self.m, self.E, self.T, self.step_px = 6, 4, 5, 2

    def window(self, x: torch.Tensor, y: torch.Tensor, n: int) -> torch.Tensor:
        """[B, 1, n, n]: 1 on the m x m patch whose top-left corner is (x - m/2, y - m/2)."""
        ar = torch.arange(n)
        rows = (ar >= (y - self.m // 2)[:, None]) & (ar < (y - self.m // 2 + self.m)[:, None])
        cols = (ar >= (x - self.m // 2)[:, None]) & (ar < (x - self.m // 2 + self.m)[:, None])
        return (rows[:, :, None] & cols[:, None, :]).float()[:, None]

    def train_step(self, images: torch.Tensor, labels: torch.Tensor, mode: int) -> None:
        B, _, n, _ = images.shape
        x, y = torch.randint(0, n, (B,)), torch.randint(0, n, (B,))
        seen = self.window(x, y, n)
        goal_layer = torch.ones(B, 1, n, n)
        log_p = torch.zeros(B)
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=self.bf16):
            for _ in range(self.E):
                where = 1 - self.window(x, y, n)
                if mode >= 2:
                    u = torch.cat([images * seen, where, 1 - seen, goal_layer], 1)
                    logits = self.run_goal(u).flatten(1).float().log_softmax(1)
                    goal = torch.multinomial(logits.exp(), 1)[:, 0]
                    log_p = log_p + logits.gather(1, goal[:, None])[:, 0]
                else:
                    goal = torch.randint(0, n * n, (B,))
                gx, gy = goal % n, goal // n
                goal_layer = 1 - self.window(gx, gy, n)
                for _ in range(self.T):
                    both = (x != gx) & (y != gy)  # only then is there an axis to choose
                    if mode >= 3:
                        u = torch.cat([images * seen, 1 - self.window(x, y, n), 1 - seen, goal_layer], 1)
                        axis_logits = self.run_action(u).mean((2, 3)).float().log_softmax(1)
                        axis = torch.multinomial(axis_logits.exp(), 1)[:, 0]
                        log_p = log_p + both.float() * axis_logits.gather(1, axis[:, None])[:, 0]
                    else:
                        axis = torch.randint(0, 2, (B,))
                    horizontal = torch.where(both, axis == 0, x != gx)
                    dx = (gx - x).clamp(-self.step_px, self.step_px)
                    dy = (gy - y).clamp(-self.step_px, self.step_px)
                    x = torch.where(horizontal, x + dx, x)
                    y = torch.where(horizontal, y, y + dy)
                    seen = torch.maximum(seen, self.window(x, y, n))
            class_log_p = self.run_classifier(images * seen).float().log_softmax(1)
            reward = class_log_p.gather(1, labels[:, None])[:, 0]
            loss = -(log_p * reward.detach() + reward).mean()
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        self.optimizer.step()


def peer_images_per_s(args, images, labels, mode: int, compiled: bool, bf16: bool) -> float:
    torch.manual_seed(args.seed)
    peer = Peer(args, compiled, bf16)
    B, N = args.batch, args.rollouts

    def batch(k: int):
        i = (k * B) % (len(images) - B)
        return images[i:i + B].repeat(N, 1, 1, 1), labels[i:i + B].repeat(N)

    warmup = args.warmup + (2 if compiled else 0)  # compiling happens in the first batches
    for k in range(warmup):
        peer.train_step(*batch(k), mode)
    start = time.perf_counter()
    for k in range(args.batches):
        peer.train_step(*batch(warmup + k), mode)
    return args.batches * B / (time.perf_counter() - start)


def scout_images_per_s(args, mode: str, precision: str) -> float:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "bench.json"
        command = [args.scout, "bench", "train", "--modes", mode, "--precision", precision,
                   "--batches", str(args.batches), "--warmup", str(args.warmup),
                   "--threads", str(args.threads), "--json", str(out), "--data", str(Path(args.data).parent),
                   "--batch", str(args.batch), "--rollouts", str(args.rollouts),
                   "--planner-width", str(args.planner_width), "--planner-depth", str(args.planner_depth),
                   "--classifier-width", str(args.classifier_width),
                   "--classifier-depth", str(args.classifier_depth)]
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            sys.exit(f"pytorch_peer: {' '.join(command)} failed ({done.returncode}): {done.stderr.strip()}")
        figures = json.loads(out.read_text())
    for entry in figures.get("modes", []):
        if entry.get("mode") == mode:
            return float(entry["images_per_s"])
    sys.exit(f"pytorch_peer: scout bench train wrote no figure for mode {mode}: {figures}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    source = Path(__file__).resolve().parent.parent
    parser.add_argument("--scout", help="the scout program to run beside the peer (default: the peer alone)")
    parser.add_argument("--data", default=str(source / "data" / "mnist"), help="MNIST folder (scout data)")
    parser.add_argument("--modes", default="iii", help="comma-separated: i, ii, iii")
    parser.add_argument("--precisions", default="fp32,bf16", help="comma-separated: fp32, bf16")
    parser.add_argument("--variants", default="eager,compiled", help="peer variants: eager, compiled")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (medians are reported)")
    parser.add_argument("--batches", type=int, default=4, help="timed batches per measurement")
    parser.add_argument("--warmup", type=int, default=1, help="untimed batches first (compiled: 2 more)")
    parser.add_argument("--batch", type=int, default=60, help="B: images per batch")
    parser.add_argument("--rollouts", type=int, default=4, help="N: rollouts per image")
    parser.add_argument("--threads", type=int, default=os.cpu_count() or 1, help="threads, for both")
    parser.add_argument("--planner-width", type=int, default=16)
    parser.add_argument("--planner-depth", type=int, default=3)
    parser.add_argument("--classifier-width", type=int, default=16)
    parser.add_argument("--classifier-depth", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", help="write the medians to this file")
    args = parser.parse_args()

    modes = [m.strip() for m in args.modes.split(",") if m.strip()]
    precisions = [p.strip() for p in args.precisions.split(",") if p.strip()]
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    for m in modes:
        if m not in MODES:
            sys.exit(f"pytorch_peer: --modes: unknown mode {m!r} (expected i, ii or iii)")
    for p in precisions:
        if p not in ("fp32", "bf16"):
            sys.exit(f"pytorch_peer: --precisions: unknown precision {p!r} (expected fp32 or bf16)")
    for v in variants:
        if v not in ("eager", "compiled"):
            sys.exit(f"pytorch_peer: --variants: unknown variant {v!r} (expected eager or compiled)")
    if "compiled" in variants and not hasattr(torch, "compile"):
        sys.exit(f"pytorch_peer: torch.compile needs PyTorch 2.x (this is {torch.__version__})")

    torch.set_num_threads(args.threads)
    data = Path(args.data)
    count = args.batch * (args.batches + args.warmup + 4)
    images = read_idx_images(data / "train-images-idx3-ubyte", count)
    labels = read_idx_labels(data / "train-labels-idx1-ubyte", count)

    runners = []
    for mode in modes:
        for precision in precisions:
            if args.scout:
                runners.append((f"Scout {mode} {precision}",
                                lambda m=mode, p=precision: scout_images_per_s(args, m, p)))
            for variant in variants:
                runners.append((f"PyTorch {variant} {mode} {precision}",
                                lambda m=mode, p=precision, v=variant: peer_images_per_s(
                                    args, images, labels, MODES[m], v == "compiled", p == "bf16")))
    results: dict[str, list[float]] = {name: [] for name, _ in runners}
    print(f"PyTorch {torch.__version__}, {args.threads} threads; {args.rounds} rounds of {args.batches} batches "
          f"of {args.batch} images x {args.rollouts} rollouts", flush=True)
    for r in range(args.rounds):
        for name, run in runners:
            value = run()
            results[name].append(value)
            print(f"round {r + 1}: {name}: {value:.1f} images/s", flush=True)

    medians = {name: statistics.median(values) for name, values in results.items()}
    print("\nmedians, images/s:")
    for mode in modes:
        for precision in precisions:
            row = []
            scout = medians.get(f"Scout {mode} {precision}")
            if scout is not None:
                row.append(f"Scout {scout:.1f}")
            peers = {v: medians[f"PyTorch {v} {mode} {precision}"] for v in variants}
            row += [f"PyTorch {v} {value:.1f}" for v, value in peers.items()]
            if scout is not None and peers:
                best = max(peers.values())
                row.append(f"Scout / faster peer {scout / best:.2f}x")
            print(f"  mode {mode} {precision}: " + ", ".join(row))
    if args.json:
        document = {"torch": torch.__version__, "threads": args.threads, "rounds": args.rounds,
                    "batches": args.batches, "medians_images_per_s": medians, "runs": results}
        tmp = Path(args.json + ".tmp")
        tmp.write_text(json.dumps(document, indent=2) + "\n")
        os.replace(tmp, args.json)


if __name__ == "__main__":
    main()
