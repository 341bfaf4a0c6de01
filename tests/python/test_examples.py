"""The examples run as a user runs them: the random agent, REINFORCE's short form, whose learned
moves must beat i.i.d. moves by at least 15 points on held-out floors, and PPO's short form
through Gymnasium, whose learned moves must beat random moves by at least 15 points for the same
fixed classifier (where Gymnasium cannot be imported, that test is skipped with one line)."""
import os
import re
import subprocess
import sys

import pytest

SOURCE = os.environ.get("SCOUT_SOURCE_DIR", os.path.dirname(os.path.dirname(os.path.dirname(__file__))))
EXAMPLES = os.path.join(SOURCE, "examples", "python")


def run(script, *args):
    result = subprocess.run([sys.executable, os.path.join(EXAMPLES, script), *args], capture_output=True, text=True,
                            timeout=1800)  # a guard against a hang, not a speed check (ASan is slow)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_the_random_agent_runs_and_pays_about_log_one_tenth():
    out = run("random_agent.py", "--num-envs", "16", "--runs", "2")
    reward = float(re.search(r"mean reward per move (-?\d+\.\d+)", out).group(1))
    assert -2.31 < reward < -2.0, out  # log(1/10) = -2.303 on every move but the reset steps'


def test_reinforce_learns_to_look_at_the_corner():
    # A fixed number of batches, not seconds: the same training on a busy or an idle machine; one
    # PyTorch thread, as two spinning threads are many times slower where other work (ctest -j,
    # a build) shares the cores (9 minutes against 2 here).
    out = run("reinforce_corner.py", "--batches", "600", "--threads", "1")
    found = re.search(r"learned moves (\d+\.\d) %, i.i.d. moves (\d+\.\d) % \(margin (-?\d+\.\d) points\)", out)
    assert found, out
    assert float(found.group(3)) >= 15.0, out


def test_ppo_through_gymnasium_learns_where_to_drive():
    try:
        import gymnasium  # noqa: F401
    except ImportError as error:
        pytest.skip(f"Gymnasium cannot be imported ({error}); CI takes it from ../shared/vendor/gymnasium-1.4.0")
    # 20 updates of 64 robots (about 20 s here), scored on 256 held-out runs.
    out = run("ppo_goals.py", "--updates", "20", "--eval-runs", "256")
    found = re.search(r"learned moves (\d+\.\d) %, random moves (\d+\.\d) % \(gain (-?\d+\.\d) points\)", out)
    assert found, out
    assert float(found.group(3)) >= 15.0, out
