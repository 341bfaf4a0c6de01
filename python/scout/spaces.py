"""Scout's spaces. Where Gymnasium imports, they are `gymnasium.spaces` objects (an action's
optional keys in an `ActionDict`, a `gymnasium.spaces.Dict`); without it, the small classes here
stand in with Gymnasium's attribute names (shape, dtype, low, high, n, nvec, spaces, contains,
`in`, seed, sample), and `to_gymnasium()` converts them where Gymnasium is installed later.
`space.seed(s)` then `space.sample()` works with both; `sample(rng)` (a NumPy Generator) only here."""
import numpy as np


class _Space:
    """seed() and the generator sample() draws from when it is given none, as Gymnasium's spaces."""
    _rng = None

    def seed(self, seed=None):
        self._rng = np.random.default_rng(seed)
        return [seed]

    def _generator(self, rng):
        if rng is not None:
            return np.random.default_rng(rng)
        if self._rng is None:
            self._rng = np.random.default_rng()
        return self._rng

try:
    import gymnasium
except ImportError:  # Gymnasium is optional
    gymnasium = None

MOVES = 4  # 0 = +x, 1 = -x, 2 = +y, 3 = -y


class Box(_Space):
    """An array of `shape` and `dtype` with every entry in [low, high]."""

    def __init__(self, low, high, shape, dtype):
        self.shape = tuple(shape)
        self.dtype = np.dtype(dtype)
        self.low = np.broadcast_to(np.asarray(low, dtype=self.dtype), self.shape).copy()
        self.high = np.broadcast_to(np.asarray(high, dtype=self.dtype), self.shape).copy()

    def contains(self, x):
        x = np.asarray(x)
        return (x.shape == self.shape and np.can_cast(x.dtype, self.dtype, "same_kind")
                and bool(np.all(x >= self.low)) and bool(np.all(x <= self.high)))

    __contains__ = contains

    def sample(self, rng=None):
        rng = self._generator(rng)
        if self.dtype.kind == "f":
            low = np.where(np.isfinite(self.low), self.low, -1.0)
            high = np.where(np.isfinite(self.high), self.high, 1.0)
            return rng.uniform(low, high).astype(self.dtype)
        return rng.integers(self.low, self.high, endpoint=True).astype(self.dtype)

    def to_gymnasium(self):
        import gymnasium
        return gymnasium.spaces.Box(self.low, self.high, self.shape, self.dtype)

    def __repr__(self):
        return f"Box({self.low.min()}, {self.high.max()}, {self.shape}, {self.dtype})"


class Discrete(_Space):
    """One integer in 0 .. n - 1."""

    def __init__(self, n):
        self.n = int(n)
        self.shape = ()
        self.dtype = np.dtype(np.int64)

    def contains(self, x):
        x = np.asarray(x)
        return x.shape == () and x.dtype.kind in "iu" and 0 <= int(x) < self.n

    __contains__ = contains

    def sample(self, rng=None):
        return np.int64(self._generator(rng).integers(self.n))

    def to_gymnasium(self):
        import gymnasium
        return gymnasium.spaces.Discrete(self.n)

    def __repr__(self):
        return f"Discrete({self.n})"


class MultiDiscrete(_Space):
    """An integer array, entry i in 0 .. nvec[i] - 1."""

    def __init__(self, nvec):
        self.nvec = np.asarray(nvec, dtype=np.int64)
        self.shape = self.nvec.shape
        self.dtype = np.dtype(np.int64)

    def contains(self, x):
        x = np.asarray(x)
        return x.shape == self.shape and x.dtype.kind in "iu" and bool(np.all((x >= 0) & (x < self.nvec)))

    __contains__ = contains

    def sample(self, rng=None):
        return self._generator(rng).integers(0, self.nvec).astype(np.int64)

    def to_gymnasium(self):
        import gymnasium
        return gymnasium.spaces.MultiDiscrete(self.nvec)

    def __repr__(self):
        return f"MultiDiscrete({self.nvec.tolist()})"


class Dict(_Space):
    """Named sub-spaces; the `optional` ones may be left out of a member."""

    def __init__(self, spaces, optional=()):
        self.spaces = dict(spaces)
        self.optional = tuple(optional)

    def __getitem__(self, key):
        return self.spaces[key]

    def keys(self):
        return self.spaces.keys()

    def contains(self, x):
        return (isinstance(x, dict) and set(self.spaces) - set(self.optional) <= set(x) <= set(self.spaces)
                and all(self.spaces[k].contains(v) for k, v in x.items()))

    __contains__ = contains

    def seed(self, seed=None):
        super().seed(seed)
        for space in self.spaces.values():
            space._rng = self._rng
        return [seed]

    def sample(self, rng=None):
        rng = self._generator(rng)
        return {k: s.sample(rng) for k, s in self.spaces.items()}

    def to_gymnasium(self):
        import gymnasium
        spaces = {k: s.to_gymnasium() for k, s in self.spaces.items()}
        if not self.optional:
            return gymnasium.spaces.Dict(spaces)
        if ActionDict is None:  # Gymnasium became importable after scout was imported
            raise RuntimeError("to_gymnasium: Gymnasium could not be imported when scout was; import it first")
        return ActionDict(spaces, optional=self.optional)

    def __repr__(self):
        return "Dict(" + ", ".join(f"{k!r}: {s!r}" for k, s in self.spaces.items()) + ")"


def _batch(space, n):
    """Scout's own batching (Gymnasium's batch_space where it is installed)."""
    if isinstance(space, Box):
        return Box(np.broadcast_to(space.low, (n, *space.shape)), np.broadcast_to(space.high, (n, *space.shape)),
                   (n, *space.shape), space.dtype)
    if isinstance(space, Discrete):
        return MultiDiscrete(np.full(n, space.n))
    if isinstance(space, MultiDiscrete):
        return MultiDiscrete(np.broadcast_to(space.nvec, (n, *space.shape)))
    return Dict({k: _batch(s, n) for k, s in space.spaces.items()}, optional=space.optional)


if gymnasium is not None:
    from gymnasium.vector.utils import batch_space, iterate

    class ActionDict(gymnasium.spaces.Dict):
        """A gymnasium.spaces.Dict whose `optional` keys may be left out of an action: the other keys
        are required. `sample()` gives every key; batch_space and iterate keep the optional keys."""

        def __init__(self, spaces=None, optional=(), seed=None, **kwargs):
            super().__init__(spaces, seed=seed, **kwargs)
            self.optional = tuple(optional)

        def contains(self, x):
            return (isinstance(x, dict) and set(self.spaces) - set(self.optional) <= x.keys() <= self.spaces.keys()
                    and all(x[k] in self.spaces[k] for k in x))

        def __eq__(self, other):
            return isinstance(other, ActionDict) and self.spaces == other.spaces and self.optional == other.optional

        def __repr__(self):
            return f"ActionDict({', '.join(f'{k!r}: {s}' for k, s in self.spaces.items())}; optional {list(self.optional)})"

    @batch_space.register(ActionDict)
    def _batch_action_dict(space, n=1):
        from copy import deepcopy
        return ActionDict({k: batch_space(s, n) for k, s in space.spaces.items()}, optional=space.optional,
                          seed=deepcopy(space.np_random))

    @iterate.register(ActionDict)
    def _iterate_action_dict(space, items):
        keys = [k for k in space.spaces if k in items and items[k] is not None]
        return (dict(zip(keys, values)) for values in zip(*(iterate(space.spaces[k], items[k]) for k in keys)))

    def _batch_with(space, n):
        return batch_space(space, n)
else:
    ActionDict = None

    def _batch_with(space, n):
        return _batch(space, n)


def describe(core):
    """The single observation and action spaces of an environment core, and batched for its robots:
    (single_observation_space, single_action_space, observation_space, action_space)."""
    S = gymnasium.spaces if gymnasium is not None else None
    box = S.Box if S else Box
    m, h, w, classes = core.patch_px, core.height, core.width, core.classes
    # In a world with teams of K robots (team.robots), each robot has its patch, pose and move:
    # those take a leading K axis; the revealed floor, seen and o are the team's.
    k = core.team_size
    team = (k,) if k > 1 else ()
    pose_high = np.broadcast_to(np.array([w - 1, h - 1], np.int32), (*team, 2))
    observation = {
        "patch": box(0.0, 1.0, (*team, m, m), np.float32),
        "pose": box(np.zeros((*team, 2), np.int32), pose_high, (*team, 2), np.int32),
        "revealed": box(0.0, 1.0, (h, w), np.float32),
        "seen": box(0, 1, (h, w), np.uint8),
    }
    if core.has_obstacles:  # o: where the robot cannot stand beside its run's obstacles
        observation["occupied"] = box(0, 1, (h, w), np.uint8)
    if core.wide_px > 0:  # the wider view: each robot's coarse window, the team's coarse map and where it is set
        observation["wide_patch"] = box(0.0, 1.0, (*team, core.wide_px, core.wide_px), np.float32)
        observation["wide_revealed"] = box(0.0, 1.0, (h, w), np.float32)
        observation["wide_seen"] = box(0, 1, (h, w), np.uint8)
    observation["time_step"] = box(0, core.episodes // k * core.steps, (), np.int32)
    single_observation = (S.Dict if S else Dict)(observation)
    multi = S.MultiDiscrete if S else MultiDiscrete
    action = {"move": multi(np.full(k, MOVES)) if k > 1 else (S.Discrete if S else Discrete)(MOVES)}
    if classes > 0:
        action["prediction"] = box(-np.inf, np.inf, (classes,), np.float32)
    action["goal"] = multi(np.broadcast_to(np.array([w, h]), (*team, 2)).copy())
    optional = [k for k in action if k != "move"]
    single_action = ActionDict(action, optional=optional) if S else Dict(action, optional=optional)
    n = core.num_envs
    return single_observation, single_action, _batch_with(single_observation, n), _batch_with(single_action, n)
