"""Scout from Python: a batched vector environment of robots that drive over MNIST floors with the
Box2D physics and the OSMesa camera in the loop, and Scout's trained agent. Where Gymnasium
imports, the environments are Gymnasium's own kind and `import scout` registers their ids:

    import gymnasium, scout
    envs = gymnasium.make_vec("scout/MNIST-v0", num_envs=64)      # or scout.make_vec("worlds/mnist.yaml", 64)
    envs = gymnasium.wrappers.vector.RecordEpisodeStatistics(envs)
    obs, info = envs.reset(seed=1)
    obs, reward, terminated, truncated, info = envs.step({"move": moves, "prediction": logits})
    env = gymnasium.make("scout/MNIST-v0")                          # one robot

Without Gymnasium the same calls work on scout.make_vec, with scout.spaces' stand-ins.
Conventions (README § Python): `move` 0 = +x (right), 1 = -x (left), 2 = +y (down), 3 = -y (up),
each a step_px move; an episode (a run) ends (terminated) after the world's E x T moves (E / K x T
steps of a team of K robots, in a world with `team`: then each env is K agents). Every
array returned is new: the next step never overwrites it. Arguments and actions are checked once,
in C++ (scout._scout): a bad one raises ValueError or TypeError with one line.
"""
import numbers
import os
from collections.abc import Mapping

import numpy as np

from . import _scout
from ._scout import __version__
from . import spaces
from .spaces import Box, Dict, MultiDiscrete, Discrete

try:
    import gymnasium
    from gymnasium.vector import AutoresetMode
except ImportError:  # Gymnasium is optional: the package works the same without it
    gymnasium = None
    AutoresetMode = None

__all__ = ["make_vec", "VectorEnv", "Env", "Agent", "checkpoint_tensors", "Box", "Dict", "Discrete", "MultiDiscrete",
           "WORLDS", "__version__"]

#: The registered ids (scout/<name>) and their world files in worlds/: the source tree's for a build
#: (build/python), the package's own (site-packages/scout/share/worlds) when installed by pip. The
#: translated and cluttered ones put the digit at a random place on a larger floor (worlds/README.md
#: § Floors larger than the digit), as the recurrent attention model's benchmarks do.
WORLDS = {"MNIST-v0": "mnist.yaml", "FashionMNIST-v0": "fashion.yaml",
          "TranslatedMNIST60-v0": "translated-60.yaml", "ClutteredMNIST60-v0": "cluttered-60.yaml",
          "ClutteredMNIST100-v0": "cluttered-100.yaml"}
_DEFAULT_WORLD = os.path.join(_scout.files_dir, "worlds", WORLDS["MNIST-v0"])
_MODES = ("NextStep", "SameStep", "Disabled")
_METADATA = {"render_modes": ["rgb_array"], "render_fps": 30}


def _autoreset_mode(value):
    value = getattr(value, "value", value)  # AutoresetMode or its value
    if value not in _MODES:
        raise ValueError(f"autoreset_mode: expected AutoresetMode.NEXT_STEP, SAME_STEP or DISABLED (or "
                         f"'NextStep', 'SameStep', 'Disabled'), got {value!r}")
    return value


def _render_mode(value):
    if value not in (None, "rgb_array"):
        raise ValueError(f"render_mode: expected None or 'rgb_array', got {value!r}")
    return value


def _reset_mask(options, allow_mask):
    """options: None, {} or (vector envs) {"reset_mask": booleans}; returns the mask or None."""
    if not options:
        return None
    if not isinstance(options, dict) or set(options) - ({"reset_mask"} if allow_mask else set()):
        expected = "None or {'reset_mask': a NumPy array of num_envs booleans}" if allow_mask else "None or {}"
        raise ValueError(f"options: expected {expected}, got {options!r}")
    return options.get("reset_mask")


if gymnasium is not None:
    _VectorBase, _EnvBase = gymnasium.vector.VectorEnv, gymnasium.Env
else:
    class _Base:
        """What gymnasium.Env and gymnasium.vector.VectorEnv give, for when Gymnasium is not installed."""
        spec = None
        render_mode = None
        closed = False
        _np_random = None

        @property
        def np_random(self):
            if self._np_random is None:
                self._np_random = np.random.default_rng()
            return self._np_random

        @np_random.setter
        def np_random(self, value):
            self._np_random = value

        @property
        def unwrapped(self):
            return self

        def reset(self, *, seed=None, options=None):
            if seed is not None:
                self._np_random = np.random.default_rng(seed)

        def close(self):
            if not self.closed:
                self.close_extras()
                self.closed = True

        def __enter__(self):  # gymnasium.Env's with-statement: closes on the way out
            return self

        def __exit__(self, *exc):
            self.close()
            return False

    _VectorBase = _EnvBase = _Base


class VectorEnv(_VectorBase):
    """num_envs robots, each over its own digit of one split (see make_vec). A
    gymnasium.vector.VectorEnv where Gymnasium imports."""

    def __init__(self, world, num_envs, seed=None, split=None, data=None, reward="dense", force=False,
                 autoreset_mode="NextStep", render_mode=None):
        mode = _autoreset_mode(autoreset_mode)
        self.render_mode = _render_mode(render_mode)
        self._core = core = _scout.VectorEnvCore(world, num_envs, seed, split, data, reward, force,
                                                 mode == "NextStep", render_mode is not None)
        self._same_step = mode == "SameStep"
        self.metadata = dict(_METADATA, autoreset_mode=AutoresetMode(mode) if AutoresetMode else mode)
        self.num_envs = core.num_envs
        self.num_classes = core.classes
        self.episodes, self.steps, self.step_px = core.episodes, core.steps, core.step_px
        (self.single_observation_space, self.single_action_space,
         self.observation_space, self.action_space) = spaces.describe(core)

    def reset(self, seed=None, options=None):
        """Starts robots on new runs: with an integer seed, robot i runs run i of that seed's
        sequence (as `scout run --seed SEED --count num_envs`); with a list of num_envs seeds,
        robot i runs its own seed's runs 0, 1, 2, ... (what SyncVectorEnv over single envs does);
        without, each robot its next run. options={"reset_mask": booleans} starts only those robots."""
        core = self._live("reset")
        result = core.reset(seed, _reset_mask(options, allow_mask=True))
        if seed is None or isinstance(seed, numbers.Integral):
            super().reset(seed=None if seed is None else int(seed))  # np_random, from an integer seed
        return result

    def step(self, actions):
        """One move per robot; returns obs, reward, terminated, truncated, info."""
        core = self._live("step")
        if not self._same_step:
            return core.step(actions)
        obs, reward, terminated, truncated, info = core.step(actions)
        if terminated.any():  # SAME_STEP: the finished robots start their next runs now
            final = obs
            obs, new_info = core.reset(None, terminated)
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in np.flatnonzero(terminated):
                final_obs[i] = {k: v[i] for k, v in final.items()}
            final_info = dict(info)
            for key in info:  # each mask its own copy: a wrapper may change one in place
                final_info["_" + key] = terminated.copy()
            new_info.update(final_obs=final_obs, _final_obs=terminated.copy(), final_info=final_info,
                            _final_info=terminated.copy())
            info = new_info
        return obs, reward, terminated, truncated, info

    def render(self):
        """Every robot's picture (render_mode="rgb_array"): a tuple of (H, W, 3) uint8 RGB arrays,
        what `scout run --video` draws after a move."""
        core = self._live("render")
        if self.render_mode is None:
            raise ValueError('render: make the environment with render_mode="rgb_array"')
        return tuple(core.render(i) for i in range(self.num_envs))

    def close_extras(self, **kwargs):
        self._core = None

    def _live(self, what):
        if self._core is None:
            raise ValueError(f"{what}: the environment is closed")
        return self._core

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return f"scout.VectorEnv(num_envs={self.num_envs}, classes={self.num_classes})"


def make_vec(world=_DEFAULT_WORLD, num_envs=1, seed=None, split=None, data=None, reward="dense", force=False,
             autoreset_mode="NextStep", render_mode=None):
    """A VectorEnv of `num_envs` robots on the world file `world` (e.g. "worlds/mnist.yaml").

    seed: the run sequence's seed (default: the world file's); robot i's j-th run is run
    j * num_envs + i of `scout run --seed SEED`. split: "train", "validation" or "test" (default:
    the world's). data: a data folder (default: $SCOUT_DATA, else where `scout data` installs: the
    source tree's data/ for a build, ~/.local/share/scout for an installed package).
    reward: "dense" (-cross-entropy of the prediction after every move) or "sparse" (after the
    last move only); 0 where no prediction is given. force: start even when the memory estimate
    (num_envs x the floor's size) exceeds what the machine has available (the smallest of
    MemAvailable, the cgroup limit and $SCOUT_MEMORY_LIMIT), which is otherwise refused.
    autoreset_mode: Gymnasium's AutoresetMode (or its value): NEXT_STEP (default), SAME_STEP or
    DISABLED. render_mode: None or "rgb_array"."""
    return VectorEnv(world, num_envs, seed=seed, split=split, data=data, reward=reward, force=force,
                     autoreset_mode=autoreset_mode, render_mode=render_mode)


def _first(batch, arrays):
    """Robot 0's entries: 0-d arrays for observations (arrays), NumPy scalars for infos."""
    return {k: v[0, ...] if arrays else v[0] for k, v in batch.items()}


class Env(_EnvBase):
    """One robot on a world file (a gymnasium.Env where Gymnasium imports; gymnasium.make("scout/
    MNIST-v0") makes one). reset(seed=s) runs run 0 of seed s's sequence, then reset() runs 1, 2,
    ...: `scout run --seed s --count K`'s runs, and what make_vec's robot i runs after
    reset(seed=[..., s, ...]) with s at i. Actions: {"move": 0..3, optional "prediction": (D,)
    logits, optional "goal": (x, y)}; the episode ends (terminated) after the world's E x T moves
    (E / K x T steps of a team of K, whose moves and goals take a leading K axis) and the next step
    needs a reset."""

    metadata = _METADATA

    def __init__(self, world=_DEFAULT_WORLD, seed=None, split=None, data=None, reward="dense", render_mode=None):
        self.render_mode = _render_mode(render_mode)
        self._core = core = _scout.VectorEnvCore(world, 1, seed, split, data, reward, False, False,
                                                 render_mode is not None)
        self.num_classes = core.classes
        self.episodes, self.steps, self.step_px = core.episodes, core.steps, core.step_px
        self.observation_space, self.action_space, _, _ = spaces.describe(core)

    def reset(self, *, seed=None, options=None):
        core = self._live("reset")
        _reset_mask(options, allow_mask=False)
        obs, info = core.reset(seed)
        super().reset(seed=int(seed) if isinstance(seed, numbers.Integral) else None)  # np_random
        return _first(obs, True), _first(info, False)

    def step(self, action):
        core = self._live("step")
        if isinstance(action, dict):
            action = {k: None if v is None else np.expand_dims(v, 0) for k, v in action.items()}
        obs, reward, terminated, truncated, info = core.step(action)
        return _first(obs, True), float(reward[0]), bool(terminated[0]), bool(truncated[0]), _first(info, False)

    def render(self):
        """The robot's picture (render_mode="rgb_array"): (H, W, 3) uint8 RGB."""
        core = self._live("render")
        if self.render_mode is None:
            raise ValueError('render: make the environment with render_mode="rgb_array"')
        return core.render(0)

    @property
    def closed(self):
        return self._core is None

    def close(self):
        self._core = None

    def _live(self, what):
        if self._core is None:
            raise ValueError(f"{what}: the environment is closed")
        return self._core

    def __repr__(self):
        return f"scout.Env(classes={self.num_classes})"


def _register():
    """Registers scout/<name> for every world in WORLDS (once per process)."""
    for name, world in WORLDS.items():
        env_id = f"scout/{name}"
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point="scout:Env", vector_entry_point="scout:make_vec",
                               kwargs={"world": os.path.join(_scout.files_dir, "worlds", world)})


if gymnasium is not None:
    _register()


def _agent_module():
    """scout._scout_agent, which links LibTorch (libtorch_cpu, libc10) and loads it with itself. Its
    RPATH finds them in the torch package installed beside scout (site-packages/torch/lib) or, in a
    build, in the one it was built against. An installed package whose torch is on another sys.path
    entry (a .pth file, the system's site packages) loads them first from the torch package Python
    imports, as the `scout` command does for the program (_scout_command.py); the dynamic linker
    then takes them by name, before any other LibTorch on the machine (Debian's libtorch-dev)."""
    if _scout.installed:
        import _scout_command  # installed with the package

        folder = _scout_command.torch_library_folder(os.path.dirname(os.path.abspath(__file__)))
        if folder is not None:
            import ctypes
            for name in ("libc10.so", "libtorch_cpu.so"):
                ctypes.CDLL(os.path.join(folder, name))
    from . import _scout_agent
    return _scout_agent


def checkpoint_tensors(path):
    """Every tensor of a Scout model or checkpoint (.safetensors; a run folder: its checkpoint) as
    Scout's own reader loads it, read back out of its networks and its optimizer: a dict of NumPy
    arrays (float32, or int64 for counts) by the names the file gives them. The file itself is a
    plain safetensors file; the `safetensors` package reads it too:

        from safetensors.numpy import load_file
        weights = load_file("models/mnist.safetensors")   # the same names and values

    LibTorch is loaded with it (the scout._scout_agent module)."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"path: expected a path to a model file or run folder, got {path!r}")
    return _agent_module().checkpoint_tensors(os.fspath(path))


class Agent:
    """Scout's trained agent (a model file or RUN/checkpoint.safetensors): its goal planner, action
    planner (where it has one: models/mnist.safetensors draws its axes i.i.d.) and classifier, driven from
    observations. With make_vec's arrays it chooses exactly what
    `scout run --checkpoint` chooses for the same seed:

        agent = scout.Agent("models/mnist.safetensors")
        obs, info = envs.reset(seed=1)
        while True:
            obs, reward, terminated, truncated, info = envs.step(agent.act(obs, info))
            if terminated.all():
                break
        logits = agent.classify(obs)       # (num_envs, D) log-probabilities

    `greedy`: the argmax goals and moves (what `scout run --greedy` chooses) instead of drawing them
    from each run's policy seed (info["policy_seed"]). `threads`: LibTorch's threads for the
    networks, 0..256 (0: one per core; a process-wide setting, the last Agent made sets it).

    `precision` is the networks' arithmetic here: "auto" (the faster on this CPU, measured
    once and cached; bf16 only where it is native; whatever the model was trained in), "bf16" or "fp32"; `agent.precision` says which
    runs, `agent.trained_precision` what the model was trained in.

    LibTorch is loaded only when an Agent is made (the scout._scout_agent module)."""

    def __init__(self, model, greedy=False, threads=0, precision="auto"):
        if not isinstance(model, (str, os.PathLike)):
            raise TypeError(f"model: expected a path to a model file or run folder, got {model!r}")
        if not isinstance(greedy, (bool, np.bool_)):  # bool("no") would be True
            raise TypeError(f"greedy: expected True or False, got {greedy!r}")
        if isinstance(threads, (bool, np.bool_)) or not isinstance(threads, numbers.Integral) or not 0 <= threads <= 256:
            raise ValueError(f"threads: expected an integer in 0..256 (0: one per core), got {threads!r}")
        if not isinstance(precision, str):  # str(None) would be refused as "None", a value never given
            raise TypeError(f"precision: expected 'auto', 'bf16' or 'fp32', got {precision!r}")
        self._core = _agent_module().AgentCore(os.fspath(model), bool(greedy), int(threads), precision)
        self.num_classes = self._core.classes
        self.precision = self._core.precision
        self.trained_precision = self._core.trained_precision

    def _robots(self, obs, info=None, need_info=False):
        """The arrays the agent reads, checked to describe the same robots and floor: integers
        that fit where integers are read, finite values in [0, 1] for the revealed floor."""
        for where, source in [("obs", obs)] + ([("info", info)] if need_info else []):
            if not isinstance(source, Mapping):
                raise TypeError(f"{where}: expected the dict make_vec's reset and step return, got "
                                f"{type(source).__name__}")

        def get(source, where, key, dtype, shape):
            if key not in source:
                raise ValueError(f"{where}[{key!r}]: missing")
            value = np.asarray(source[key])
            if value.shape != shape:
                raise ValueError(f"{where}[{key!r}]: expected shape {shape}, got {value.shape}")
            if dtype is float:  # the revealed floor: any real numbers (checked for [0, 1] below)
                dtype = np.float32
                if value.dtype.kind not in "biuf":
                    raise TypeError(f"{where}[{key!r}]: expected numbers, got dtype {value.dtype}")
            elif value.dtype.kind not in "biu":  # a float pose or seed is refused, not truncated
                raise TypeError(f"{where}[{key!r}]: expected integers, got dtype {value.dtype}")
            elif dtype is not bool and value.dtype.kind != "b" and value.size:  # nothing wraps around
                limits = np.iinfo(dtype)
                low, high = value.min(), value.max()
                if low < limits.min or high > limits.max:
                    raise ValueError(f"{where}[{key!r}]: expected values that fit {np.dtype(dtype).name}, "
                                     f"got {low if low < limits.min else high}")
            return np.ascontiguousarray(value, dtype=dtype)
        seen = np.asarray(obs["seen"]) if "seen" in obs else None
        if seen is None or seen.ndim != 3 or seen.shape[0] < 1:
            raise ValueError("obs['seen']: expected shape (num_envs, H, W) with num_envs >= 1")
        n, h, w = seen.shape
        patch = np.asarray(obs.get("patch", np.empty(0)))
        if patch.ndim == 4:
            raise ValueError(f"obs['patch']: shape {patch.shape} is a world with teams of {patch.shape[1]} robots; "
                             "scout.Agent drives one robot per environment (team.robots: 1)")
        if patch.ndim != 3 or patch.shape[0] != n or patch.shape[1] != patch.shape[2]:
            raise ValueError(f"obs['patch']: expected shape ({n}, m, m), got {patch.shape}")
        revealed = get(obs, "obs", "revealed", float, (n, h, w))
        if not (np.all(revealed >= 0) and np.all(revealed <= 1)):  # NaN fails both
            bad = revealed[~((revealed >= 0) & (revealed <= 1))][0]
            raise ValueError(f"obs['revealed']: expected values in [0, 1] (the floor's pixels / 255), got {bad}")
        arrays = {"pose": get(obs, "obs", "pose", np.int32, (n, 2)),
                  "seen": get(obs, "obs", "seen", np.uint8, (n, h, w)),
                  "revealed": revealed,
                  # o, in worlds with obstacles (a model with the occupancy channel reads zeros without it)
                  "occupied": get(obs, "obs", "occupied", np.uint8, (n, h, w)) if "occupied" in obs else None,
                  "patch_px": int(patch.shape[1])}
        if self._core.wide_view:  # the wider view's coarse map, in worlds with one (camera.wide_px)
            if "wide_revealed" not in obs or "wide_seen" not in obs:
                raise ValueError("scout.Agent: the model's planners read the wider view (--wide-view): expected "
                                 "obs['wide_revealed'] and obs['wide_seen'], which a world with camera.wide_px gives")
            wide = get(obs, "obs", "wide_revealed", float, (n, h, w))
            if not (np.all(wide >= 0) and np.all(wide <= 1)):
                raise ValueError("obs['wide_revealed']: expected values in [0, 1] (the coarse map's pixels / 255)")
            arrays.update(wide_revealed=wide, wide_seen=get(obs, "obs", "wide_seen", np.uint8, (n, h, w)))
        else:
            arrays.update(wide_revealed=None, wide_seen=None)
        if need_info:
            arrays.update(time_step=get(obs, "obs", "time_step", np.int32, (n,)),
                          policy_seed=get(info, "info", "policy_seed", np.uint64, (n,)),
                          episode=get(info, "info", "goal_episode", np.int32, (n,)),
                          episode_start=get(info, "info", "goal_episode_start", bool, (n,)))
        return arrays

    def act(self, obs, info):
        """The action dict for the next move: the planners' moves and the episode's goals (the goal
        keeps each move from passing it, as the paper's protocol does)."""
        a = self._robots(obs, info, need_info=True)
        moves, goals = self._core.act(a["pose"], a["seen"], a["revealed"], a["time_step"], a["policy_seed"],
                                      a["episode"], a["episode_start"], a["patch_px"], a["occupied"],
                                      a["wide_revealed"], a["wide_seen"])
        return {"move": moves, "goal": goals}

    def classify(self, obs):
        """log pi_c: the classifier's log-probabilities (num_envs, D) on what each robot revealed."""
        a = self._robots(obs)
        return self._core.classify(a["pose"], a["seen"], a["revealed"], a["patch_px"])
