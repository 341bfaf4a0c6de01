"""The Python package end to end (real Box2D, OSMesa and LibTorch): scout.Agent driving make_vec
reproduces `scout run --checkpoint` bit for bit; observations match the described spaces;
autoreset; determinism; every bad input is one clear exception; memory stays flat over 10^6
agent-steps. ctest runs this with PYTHONPATH=build/python, SCOUT_BINARY and SCOUT_SOURCE_DIR set."""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import scout

SOURCE = os.environ.get("SCOUT_SOURCE_DIR", os.path.dirname(os.path.dirname(os.path.dirname(__file__))))
BINARY = os.environ.get("SCOUT_BINARY", os.path.join(SOURCE, "build", "tools", "scout"))
WORLD = os.path.join(SOURCE, "worlds", "mnist.yaml")
MODEL = os.path.join(SOURCE, "tests", "data", "mnist-8k-v1.pt")
DATA = os.path.join(os.environ.get("SCOUT_DATA", os.path.join(SOURCE, "data")), "mnist")


@pytest.fixture(scope="module", autouse=True)
def installed_data():
    assert os.path.exists(os.path.join(DATA, "t10k-images-idx3-ubyte")), (
        f"{DATA} is missing: install the data with ./scripts/setup.sh (MNIST alone: scout data)")


def drive(envs, agent, seed):
    obs, info = envs.reset(seed=seed)
    first_info = info
    poses, goals = [obs["pose"].copy()], []
    while True:
        action = agent.act(obs, info)
        goals.append(action["goal"].copy())
        obs, reward, terminated, truncated, info = envs.step(action)
        poses.append(obs["pose"].copy())
        if terminated.all():
            return first_info, np.stack(poses), np.stack(goals), agent.classify(obs)


def test_the_agent_through_make_vec_is_scout_run_bit_for_bit(tmp_path):
    # 241 robots: `scout run` drives them in batches of 240 and 1, the Agent all at once.
    n, seed = 241, 17
    out = tmp_path / "run"
    subprocess.run([BINARY, "run", WORLD, "--checkpoint", MODEL, "--seed", str(seed), "--count", str(n),
                    "--no-images", "--out", str(out)], check=True, capture_output=True)
    runs = json.loads((out / "trajectory.json").read_text())["runs"]
    envs = scout.make_vec(WORLD, n, seed=seed)
    info, poses, goals, logits = drive(envs, scout.Agent(MODEL), seed)
    for i, run in enumerate(runs):
        assert info["index"][i] == run["index"]
        assert info["label"][i] == run["label"]
        assert list(poses[0, i]) == run["start"]
        assert [list(p) for p in poses[1:, i]] == [s["grid_pose"] for s in run["steps"]]
        assert [list(g) for g in goals[:, i]] == [s["goal"] for s in run["steps"]]
        probabilities = np.exp(logits[i])
        assert np.allclose(probabilities, run["probabilities"], atol=1e-6), (probabilities, run["probabilities"])
        assert int(np.argmax(logits[i])) == run["prediction"]


def test_the_agent_runs_in_the_precision_asked_for_as_scout_run_does(tmp_path):
    # The model was trained in bf16; fp32 asked for runs fp32 and chooses what `scout run
    # --precision fp32` chooses.
    n, seed = 8, 4
    out = tmp_path / "run"
    subprocess.run([BINARY, "run", WORLD, "--checkpoint", MODEL, "--precision", "fp32", "--seed", str(seed),
                    "--count", str(n), "--no-images", "--out", str(out)], check=True, capture_output=True)
    runs = json.loads((out / "trajectory.json").read_text())["runs"]
    agent = scout.Agent(MODEL, precision="fp32")
    assert (agent.precision, agent.trained_precision) == ("fp32", "bf16")
    _, poses, goals, logits = drive(scout.make_vec(WORLD, n, seed=seed), agent, seed)
    for i, run in enumerate(runs):
        assert [list(p) for p in poses[1:, i]] == [s["grid_pose"] for s in run["steps"]]
        assert np.allclose(np.exp(logits[i]), run["probabilities"], atol=1e-6)
    with pytest.raises(ValueError, match="precision"):
        scout.Agent(MODEL, precision="fp16")


def test_the_agents_auto_precision_is_fp32_where_bf16_is_not_native():
    # oneDNN capped to AVX2: the stand-in for a CPU without native bf16.
    env = dict(os.environ, ONEDNN_MAX_CPU_ISA="AVX2", ATEN_CPU_CAPABILITY="avx2")
    probe = "import scout; a = scout.Agent(%r); print(a.precision, a.trained_precision)" % MODEL
    result = subprocess.run([sys.executable, "-c", probe], env=env, check=True, capture_output=True, text=True)
    assert result.stdout.split() == ["fp32", "bf16"], result.stderr


def test_observations_match_the_described_spaces_and_are_never_overwritten():
    envs = scout.make_vec(WORLD, 6, seed=3)
    obs, info = envs.reset()
    assert envs.observation_space.contains(obs)
    assert envs.single_observation_space["patch"].shape == (6, 6)
    assert envs.action_space["move"].shape == (6,)
    assert envs.action_space["prediction"].shape == (6, 10)
    for key, space in envs.observation_space.spaces.items():
        assert obs[key].dtype == space.dtype, key
        assert obs[key].shape == space.shape, key
    kept = {k: v.copy() for k, v in obs.items()}
    rng = np.random.default_rng(0)
    obs2, reward, terminated, truncated, info2 = envs.step({"move": rng.integers(0, 4, 6)})
    for key in kept:
        assert np.array_equal(obs[key], kept[key]), f"obs[{key!r}] was overwritten by the next step"
    assert envs.observation_space.contains(obs2)
    # The revealed floor is the digit where seen, 0 elsewhere; the patch is the floor at the pose.
    assert np.all(obs2["revealed"][obs2["seen"] == 0] == 0)
    assert reward.dtype == np.float32 and terminated.dtype == bool and truncated.dtype == bool
    assert set(info2) >= {"label", "index", "pose_m"}
    assert np.allclose(info2["pose_m"], (obs2["pose"] + 0.5) * 0.1, atol=0.01)


def test_episodes_end_after_e_times_t_moves_then_autoreset_next_step():
    n = 4
    envs = scout.make_vec(WORLD, n, seed=8)
    obs, info = envs.reset()
    first = info["index"].copy()
    moves = np.zeros(n, np.int64)
    for t in range(1, 21):
        obs, reward, terminated, truncated, info = envs.step({"move": moves})
        assert np.all(obs["time_step"] == t)
        assert terminated.all() == (t == 20)
        assert not truncated.any()
    logits = np.zeros((n, 10), np.float32)
    obs, reward, terminated, truncated, info = envs.step({"move": moves, "prediction": logits})
    assert np.all(obs["time_step"] == 0)
    assert not terminated.any()
    assert np.all(reward == 0), "a reset step pays nothing"
    # The next runs of the sequence: robot i's second run is run n + i of `scout run --seed 8`.
    again = scout.make_vec(WORLD, 2 * n, seed=8)
    _, both = again.reset()
    assert np.array_equal(first, both["index"][:n])
    assert np.array_equal(info["index"], both["index"][n:])


def test_dense_and_sparse_rewards():
    for kind in ("dense", "sparse"):
        envs = scout.make_vec(WORLD, 3, seed=2, reward=kind)
        _, info = envs.reset()
        logits = np.full((3, 10), -2.0, np.float32)
        logits[np.arange(3), info["label"]] = 3.0
        expected = 3.0 - np.log(np.exp(3.0) + 9 * np.exp(-2.0))
        for t in range(1, 21):
            _, reward, terminated, _, _ = envs.step({"move": np.full(3, 2), "prediction": logits})
            want = expected if kind == "dense" or t == 20 else 0.0
            assert np.allclose(reward, want, atol=1e-5), (kind, t, reward)


def test_the_same_seed_and_moves_give_the_same_everything():
    a, b = scout.make_vec(WORLD, 8, seed=4), scout.make_vec(WORLD, 8, seed=4)
    oa, _ = a.reset()
    ob, _ = b.reset()
    rng = np.random.default_rng(5)
    for _ in range(25):
        move = rng.integers(0, 4, 8)
        oa, ra, *_ = a.step({"move": move})
        ob, rb, *_ = b.step({"move": move})
        for key in oa:
            assert np.array_equal(oa[key], ob[key]), key
    c = scout.make_vec(WORLD, 8, seed=5)
    oc, ic = c.reset()
    _, ia = a.reset(seed=4)
    assert not np.array_equal(ia["index"], ic["index"])


@pytest.mark.parametrize("action, error, message", [
    ({"move": np.zeros(3, np.int64)}, ValueError, "action['move']: expected shape (4,), got (3,)"),
    ({"move": np.zeros(4, np.float32)}, TypeError, "action['move']: expected integers, got dtype float32"),
    ({"move": np.array([0, 1, 4, 0])}, ValueError, "action['move'][2]: expected 0, 1, 2 or 3 (+x, -x, +y, -y), got 4"),
    ({"move": np.array([0, -1, 0, 0])}, ValueError, "action['move'][1]: expected 0, 1, 2 or 3"),
    ({"move": np.zeros(4, int), "prediction": np.full((4, 10), np.nan, np.float32)}, ValueError,
     "action['prediction'][0][0]: expected a finite logit, got nan"),
    ({"move": np.zeros(4, int), "prediction": np.zeros((4, 9), np.float32)}, ValueError,
     "action['prediction']: expected shape (4, 10), got (4, 9)"),
    ({"move": np.zeros(4, int), "speed": 1}, ValueError, "action: unknown key(s) ['speed']"),
    ([0, 0, 0, 0], TypeError, "action: expected a dict"),
])
def test_bad_actions_raise_one_clear_line(action, error, message):
    envs = scout.make_vec(WORLD, 4, seed=1)
    envs.reset()
    with pytest.raises(error) as caught:
        envs.step(action)
    text = str(caught.value)
    assert "\n" not in text
    assert text.startswith(message), text


@pytest.mark.parametrize("kwargs, error, message", [
    ({"world": "no-such-world.yaml"}, ValueError, "no-such-world.yaml: cannot open world file"),
    ({"split": "holdout"}, ValueError, "split: expected 'train', 'validation' or 'test', got 'holdout'"),
    ({"num_envs": 0}, ValueError, "num_envs: expected an integer in 1..4096 (the camera's batch), got 0"),
    ({"num_envs": 2**40}, ValueError, "num_envs: expected an integer in 1..4096"),
    ({"num_envs": 2.5}, TypeError, "num_envs: expected a positive integer"),
    ({"seed": -1}, ValueError, "seed: expected an integer in [0, 2**64), got -1"),
    ({"reward": "shaped"}, ValueError, "reward: expected 'dense' or 'sparse'"),
    ({"data": "/no/such/folder"}, ValueError, "worlds/mnist.yaml:3: floor.dataset:"),
])
def test_bad_arguments_raise_one_clear_line(kwargs, error, message):
    args = {"world": WORLD, "num_envs": 2}
    args.update(kwargs)
    with pytest.raises(error) as caught:
        scout.make_vec(**args)
    text = str(caught.value)
    assert "\n" not in text
    assert message in text, text


def test_more_robots_than_memory_allows_are_refused_unless_forced(monkeypatch):
    # A user's cap stands for a small machine: 4096 robots need more than 64 MiB, 2 fit with force.
    monkeypatch.setenv("SCOUT_MEMORY_LIMIT", "64M")
    with pytest.raises(ValueError) as caught:
        scout.make_vec(WORLD, 4096)
    text = str(caught.value)
    assert "\n" not in text
    assert text.startswith("num_envs = 4096 robots on 28 x 28 floors needs about "), text
    assert "64.0 MiB is available (SCOUT_MEMORY_LIMIT); ask for less, or pass force=True" in text, text
    envs = scout.make_vec(WORLD, 2, force=True)
    obs, _ = envs.reset(seed=1)
    assert obs["seen"].shape == (2, 28, 28)


def resident_kib():
    """The process's resident memory now (not its peak), KiB."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * (os.sysconf("SC_PAGE_SIZE") // 1024)


def test_a_million_agent_steps_keep_memory_flat():
    n = 250
    envs = scout.make_vec(WORLD, n, seed=6)
    envs.reset()
    moves = np.random.default_rng(1).integers(0, 4, (64, n))
    logits = np.zeros((n, 10), np.float32)
    for k in range(400):  # warm up the allocator
        envs.step({"move": moves[k % 64], "prediction": logits})
    before = resident_kib()
    for k in range(4000):  # 4,000 x 250 = 10^6 agent-steps
        obs, *_ = envs.step({"move": moves[k % 64], "prediction": logits})
    grown_kib = resident_kib() - before
    # A leak of even one small array per step (a reward vector is 1 KiB) would grow by 4 MiB.
    assert grown_kib < 2048, f"resident memory grew by {grown_kib} KiB over 10^6 agent-steps"
