"""Space descriptions with Gymnasium's attribute names (shape, dtype, low, high, n, nvec, spaces,
contains, sample). Gymnasium itself is not a dependency (Debian 12 does not package it); where it
is installed, `to_gymnasium()` converts a description into the real thing."""
import numpy as np


class Box:
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

    def sample(self, rng=None):
        rng = np.random.default_rng(rng)
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


class Discrete:
    """One integer in 0 .. n - 1."""

    def __init__(self, n):
        self.n = int(n)
        self.shape = ()
        self.dtype = np.dtype(np.int64)

    def contains(self, x):
        x = np.asarray(x)
        return x.shape == () and x.dtype.kind in "iu" and 0 <= int(x) < self.n

    def sample(self, rng=None):
        return np.int64(np.random.default_rng(rng).integers(self.n))

    def to_gymnasium(self):
        import gymnasium
        return gymnasium.spaces.Discrete(self.n)

    def __repr__(self):
        return f"Discrete({self.n})"


class MultiDiscrete:
    """An integer array, entry i in 0 .. nvec[i] - 1."""

    def __init__(self, nvec):
        self.nvec = np.asarray(nvec, dtype=np.int64)
        self.shape = self.nvec.shape
        self.dtype = np.dtype(np.int64)

    def contains(self, x):
        x = np.asarray(x)
        return x.shape == self.shape and x.dtype.kind in "iu" and bool(np.all((x >= 0) & (x < self.nvec)))

    def sample(self, rng=None):
        return np.random.default_rng(rng).integers(0, self.nvec).astype(np.int64)

    def to_gymnasium(self):
        import gymnasium
        return gymnasium.spaces.MultiDiscrete(self.nvec)

    def __repr__(self):
        return f"MultiDiscrete({self.nvec.tolist()})"


class Dict:
    """Named sub-spaces."""

    def __init__(self, spaces):
        self.spaces = dict(spaces)

    def __getitem__(self, key):
        return self.spaces[key]

    def keys(self):
        return self.spaces.keys()

    def contains(self, x):
        return isinstance(x, dict) and set(x) == set(self.spaces) and all(
            s.contains(x[k]) for k, s in self.spaces.items())

    def sample(self, rng=None):
        rng = np.random.default_rng(rng)
        return {k: s.sample(rng) for k, s in self.spaces.items()}

    def to_gymnasium(self):
        import gymnasium
        return gymnasium.spaces.Dict({k: s.to_gymnasium() for k, s in self.spaces.items()})

    def __repr__(self):
        return "Dict(" + ", ".join(f"{k!r}: {s!r}" for k, s in self.spaces.items()) + ")"
