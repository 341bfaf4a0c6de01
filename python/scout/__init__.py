"""Scout from Python: a batched, Gymnasium-style vector environment of robots that drive over
MNIST floors with the Box2D physics and the OSMesa camera in the loop, and Scout's trained agent.

    import scout
    envs = scout.make_vec("worlds/mnist.yaml", num_envs=240, seed=1)
    obs, info = envs.reset()
    obs, reward, terminated, truncated, info = envs.step({"move": moves})

Conventions (README § Python): `move` 0 = +x (right), 1 = -x (left), 2 = +y (down), 3 = -y (up),
each a step_px move; an episode ends (terminated) after the world's E x T moves and the next step
starts that robot's next run, ignoring its action (Gymnasium's NEXT_STEP autoreset). Every array
returned is new: the next step never overwrites it.
"""
import numbers
import os

import numpy as np

from . import _scout
from ._scout import __version__

_MAX_ENVS = 4096  # the camera's batch
from .spaces import Box, Dict, MultiDiscrete, Discrete

__all__ = ["make_vec", "VectorEnv", "Agent", "Box", "Dict", "Discrete", "MultiDiscrete", "__version__"]

_MOVES = 4


def _seed(value, name="seed"):
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name}: expected an integer in [0, 2**64) or None, got {value!r}")
    value = int(value)
    if not 0 <= value < 2**64:
        raise ValueError(f"{name}: expected an integer in [0, 2**64), got {value}")
    return value


def _array(action, key, kinds, shape, dtype):
    value = np.asarray(action[key])
    if value.dtype.kind not in kinds:
        raise TypeError(f"action[{key!r}]: expected {'integers' if 'i' in kinds else 'floats'}, "
                        f"got dtype {value.dtype}")
    if value.shape != shape:
        raise ValueError(f"action[{key!r}]: expected shape {shape}, got {value.shape}")
    return value


class VectorEnv:
    """num_envs robots, each over its own digit of one split (see the module's docstring)."""

    metadata = {"autoreset_mode": "NextStep"}

    def __init__(self, world, num_envs, seed=None, split=None, data=None, reward="dense", force=False):
        if isinstance(num_envs, (bool, np.bool_)) or not isinstance(num_envs, numbers.Integral):
            raise TypeError(f"num_envs: expected a positive integer, got {num_envs!r}")
        if not 1 <= int(num_envs) <= _MAX_ENVS:
            raise ValueError(f"num_envs: expected an integer in 1..{_MAX_ENVS} (the camera's batch), got {num_envs}")
        if not isinstance(world, (str, os.PathLike)):
            raise TypeError(f"world: expected a path to a world file, got {world!r}")
        if split is not None and split not in ("train", "validation", "test"):
            raise ValueError(f"split: expected 'train', 'validation' or 'test', got {split!r}")
        if reward not in ("dense", "sparse"):
            raise ValueError(f"reward: expected 'dense' or 'sparse', got {reward!r}")
        self._core = _scout.VectorEnvCore(os.fspath(world), int(num_envs), _seed(seed), split,
                                          None if data is None else os.fspath(data), reward, bool(force))
        core = self._core
        self.num_envs = core.num_envs
        self.num_classes = core.classes
        self.episodes, self.steps, self.step_px = core.episodes, core.steps, core.step_px
        n, m, h, w = core.num_envs, core.patch_px, core.height, core.width
        self.single_observation_space = Dict({
            "patch": Box(0.0, 1.0, (m, m), np.float32),
            "pose": Box(np.zeros(2, np.int32), np.array([w - 1, h - 1], np.int32), (2,), np.int32),
            "revealed": Box(0.0, 1.0, (h, w), np.float32),
            "seen": Box(0, 1, (h, w), np.uint8),
            "time_step": Box(0, self.episodes * self.steps, (), np.int32),
        })
        self.observation_space = Dict({
            "patch": Box(0.0, 1.0, (n, m, m), np.float32),
            "pose": Box(np.zeros((n, 2), np.int32), np.tile(np.array([w - 1, h - 1], np.int32), (n, 1)), (n, 2),
                        np.int32),
            "revealed": Box(0.0, 1.0, (n, h, w), np.float32),
            "seen": Box(0, 1, (n, h, w), np.uint8),
            "time_step": Box(0, self.episodes * self.steps, (n,), np.int32),
        })
        single_action = {"move": Discrete(_MOVES)}
        batch_action = {"move": MultiDiscrete(np.full(n, _MOVES))}
        if self.num_classes > 0:
            single_action["prediction"] = Box(-np.inf, np.inf, (self.num_classes,), np.float32)
            batch_action["prediction"] = Box(-np.inf, np.inf, (n, self.num_classes), np.float32)
        self.single_action_space = Dict(single_action)
        self.action_space = Dict(batch_action)

    def reset(self, seed=None, options=None):
        """Starts every robot on a new run: with a seed, runs 0 .. num_envs - 1 of that seed (as
        `scout run --seed SEED --count num_envs`); without, each robot's next run."""
        if self._core is None:
            raise ValueError("reset: the environment is closed")
        if options:
            raise ValueError(f"options: expected None, got {options!r}")
        return self._core.reset(_seed(seed))

    def step(self, action):
        """One move per robot; returns obs, reward, terminated, truncated, info."""
        if not isinstance(action, dict):
            raise TypeError(f"action: expected a dict with 'move' (and optionally 'prediction', 'goal'), "
                            f"got {type(action).__name__}")
        unknown = set(action) - {"move", "prediction", "goal"}
        if unknown:
            raise ValueError(f"action: unknown key(s) {sorted(unknown)}; expected 'move', 'prediction', 'goal'")
        if "move" not in action:
            raise ValueError("action: expected a 'move' entry")
        if self._core is None:
            raise ValueError("step: the environment is closed")
        n = self.num_envs
        move = _array(action, "move", "iu", (n,), np.int32)
        bad = np.flatnonzero((move < 0) | (move >= _MOVES))
        if bad.size:
            i = int(bad[0])
            raise ValueError(f"action['move'][{i}]: expected 0, 1, 2 or 3 (+x, -x, +y, -y), got {move[i]}")
        move = np.ascontiguousarray(move, dtype=np.int32)
        prediction = goal = None
        if action.get("prediction") is not None:
            if self.num_classes == 0:
                raise ValueError("action['prediction']: the floors have no labels to predict")
            prediction = _array(action, "prediction", "f", (n, self.num_classes), np.float32)
            too_big = np.flatnonzero(np.isfinite(prediction) & (np.abs(prediction) > np.finfo(np.float32).max))
            if too_big.size:
                i, j = divmod(int(too_big[0]), self.num_classes)
                raise ValueError(f"action['prediction'][{i}][{j}]: expected a logit within float32's range, "
                                 f"got {prediction[i, j]}")
            prediction = np.ascontiguousarray(prediction, dtype=np.float32)
        if action.get("goal") is not None:
            goal = _array(action, "goal", "iu", (n, 2), np.int32)
            bad = np.flatnonzero(((goal < 0) | (goal > np.iinfo(np.int32).max)).any(axis=1))
            if bad.size:
                i = int(bad[0])
                raise ValueError(f"action['goal'][{i}]: expected a cell of the floor, got {tuple(goal[i])}")
            goal = np.ascontiguousarray(goal, dtype=np.int32)
        return self._core.step(move, prediction, goal)

    def close(self):
        self._core = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return f"scout.VectorEnv(num_envs={self.num_envs}, classes={self.num_classes})"


def make_vec(world, num_envs, seed=None, split=None, data=None, reward="dense", force=False):
    """A VectorEnv of `num_envs` robots on the world file `world` (e.g. "worlds/mnist.yaml").

    seed: the run sequence's seed (default: the world file's); robot i's j-th run is run
    j * num_envs + i of `scout run --seed SEED`. split: "train", "validation" or "test" (default:
    the world's). data: a data folder (default: $SCOUT_DATA, else the source tree's data/).
    reward: "dense" (-cross-entropy of the prediction after every move) or "sparse" (after the
    last move only); 0 where no prediction is given. force: start even when the memory estimate
    (num_envs x the floor's size) exceeds what the machine has available (the smallest of
    MemAvailable, the cgroup limit and $SCOUT_MEMORY_LIMIT), which is otherwise refused."""
    return VectorEnv(world, num_envs, seed=seed, split=split, data=data, reward=reward, force=force)


class Agent:
    """Scout's trained agent (a model file or RUN/checkpoint.pt): its goal planner, action planner
    and classifier, driven from observations. With make_vec's arrays it chooses exactly what
    `scout run --checkpoint` chooses for the same seed:

        agent = scout.Agent("models/mnist.pt")
        obs, info = envs.reset(seed=1)
        while True:
            obs, reward, terminated, truncated, info = envs.step(agent.act(obs, info))
            if terminated.all():
                break
        logits = agent.classify(obs)       # (num_envs, D) log-probabilities

    `precision` is the networks' arithmetic here: "auto" (bf16 where this CPU has native bf16,
    else fp32, whatever the model was trained in), "bf16" or "fp32"; `agent.precision` says which
    runs, `agent.trained_precision` what the model was trained in.

    LibTorch is loaded only when an Agent is made (the scout._scout_agent module)."""

    def __init__(self, model, greedy=False, threads=0, precision="auto"):
        if not isinstance(model, (str, os.PathLike)):
            raise TypeError(f"model: expected a path to a model file or run folder, got {model!r}")
        if isinstance(threads, (bool, np.bool_)) or not isinstance(threads, numbers.Integral) or not 0 <= threads <= 256:
            raise ValueError(f"threads: expected an integer in 0..256 (0: one per core), got {threads!r}")
        from . import _scout_agent  # LibTorch comes with it
        self._core = _scout_agent.AgentCore(os.fspath(model), bool(greedy), int(threads), str(precision))
        self.num_classes = self._core.classes
        self.precision = self._core.precision
        self.trained_precision = self._core.trained_precision

    @staticmethod
    def _robots(obs, info=None):
        """The arrays the agent reads, checked to describe the same robots and floor."""
        def get(source, where, key, dtype, shape):
            if key not in source:
                raise ValueError(f"{where}[{key!r}]: missing")
            value = np.asarray(source[key])
            if value.shape != shape:
                raise ValueError(f"{where}[{key!r}]: expected shape {shape}, got {value.shape}")
            return np.ascontiguousarray(value, dtype=dtype)
        seen = np.asarray(obs["seen"]) if "seen" in obs else None
        if seen is None or seen.ndim != 3 or seen.shape[0] < 1:
            raise ValueError("obs['seen']: expected shape (num_envs, H, W) with num_envs >= 1")
        n, h, w = seen.shape
        patch = np.asarray(obs.get("patch", np.empty(0)))
        if patch.ndim != 3 or patch.shape[0] != n or patch.shape[1] != patch.shape[2]:
            raise ValueError(f"obs['patch']: expected shape ({n}, m, m), got {patch.shape}")
        arrays = {"pose": get(obs, "obs", "pose", np.int32, (n, 2)),
                  "seen": get(obs, "obs", "seen", np.uint8, (n, h, w)),
                  "revealed": get(obs, "obs", "revealed", np.float32, (n, h, w)),
                  "patch_px": int(patch.shape[1])}
        if info is not None:
            arrays.update(time_step=get(obs, "obs", "time_step", np.int32, (n,)),
                          policy_seed=get(info, "info", "policy_seed", np.uint64, (n,)),
                          episode=get(info, "info", "episode", np.int32, (n,)),
                          episode_start=get(info, "info", "episode_start", bool, (n,)))
        return arrays

    def act(self, obs, info):
        """The action dict for the next move: the planners' moves and the episode's goals (the goal
        keeps each move from passing it, as the paper's protocol does)."""
        a = self._robots(obs, info)
        moves, goals = self._core.act(a["pose"], a["seen"], a["revealed"], a["time_step"], a["policy_seed"],
                                      a["episode"], a["episode_start"], a["patch_px"])
        return {"move": moves, "goal": goals}

    def classify(self, obs):
        """log pi_c: the classifier's log-probabilities (num_envs, D) on what each robot revealed."""
        a = self._robots(obs)
        return self._core.classify(a["pose"], a["seen"], a["revealed"], a["patch_px"])
