"""A pytest plugin (`-p hide_gymnasium`) that makes `import gymnasium` fail in the test process, as
on a machine where Gymnasium is not installed: test_scout_env checks that the package works the
same without it (scout.spaces' stand-ins and scout's own base classes). The probes it starts in
child interpreters (precision and threads) do not depend on Gymnasium either way."""
import sys

sys.modules["gymnasium"] = None  # `import gymnasium` now raises ImportError
