"""The Python package end to end (real Box2D, OSMesa and LibTorch): scout.Agent driving make_vec
reproduces `scout run --checkpoint` bit for bit, in the precision asked for and greedy as `scout run
--greedy`; its threads are the ones asked for; observations match the described spaces; autoreset;
determinism; split= and data= pick the digits the IDX files hold; close() and the with-statement
release the environment; every bad input (to make_vec, scout.Env or scout.Agent) is one clear
exception; memory stays flat over 10^6 agent-steps. ctest runs this with PYTHONPATH=build/python,
SCOUT_BINARY and SCOUT_SOURCE_DIR set."""
import gc
import json
import os
import subprocess
import sys
import weakref

import numpy as np
import pytest

import scout

SOURCE = os.environ.get("SCOUT_SOURCE_DIR", os.path.dirname(os.path.dirname(os.path.dirname(__file__))))
BINARY = os.environ.get("SCOUT_BINARY", os.path.join(SOURCE, "build", "tools", "scout"))
WORLD = os.path.join(SOURCE, "worlds", "mnist.yaml")
MODEL = os.path.join(SOURCE, "tests", "data", "mnist-8k-v1.safetensors")
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


def run_both_ways(tmp_path, world, model, n, seed):
    """`scout run`'s runs of `model` in `world`, and the same robots driven by scout.Agent through
    make_vec: (runs, info, poses, goals, logits)."""
    out = tmp_path / "run"
    subprocess.run([BINARY, "run", world, "--checkpoint", model, "--seed", str(seed), "--count", str(n),
                    "--no-images", "--out", str(out)], check=True, capture_output=True)
    runs = json.loads((out / "trajectory.json").read_text())["runs"]
    return (runs, *drive(scout.make_vec(world, n, seed=seed), scout.Agent(model), seed))


def test_the_agent_through_make_vec_is_scout_run_bit_for_bit(tmp_path):
    # 241 robots: `scout run` drives them in batches of 240 and 1, the Agent all at once.
    runs, info, poses, goals, logits = run_both_ways(tmp_path, WORLD, MODEL, n=241, seed=17)
    for i, run in enumerate(runs):
        assert info["index"][i] == run["index"]
        assert info["label"][i] == run["label"]
        assert list(poses[0, i]) == run["start"]
        assert [list(p) for p in poses[1:, i]] == [s["grid_pose"] for s in run["steps"]]
        assert [list(g) for g in goals[:, i]] == [s["goal"] for s in run["steps"]]
        probabilities = np.exp(logits[i])
        assert np.allclose(probabilities, run["probabilities"], atol=1e-6), (probabilities, run["probabilities"])
        assert int(np.argmax(logits[i])) == run["prediction"]


def test_the_route_rule_agent_among_boxes_is_scout_run_bit_for_bit(tmp_path):
    # models/obstacles-random.safetensors drives by the route rule, which reads obs["occupied"]
    # and the model's step: through make_vec it takes the goals and moves `scout run` takes.
    world = os.path.join(SOURCE, "worlds", "scenarios", "obstacles-random.yaml")
    model = os.path.join(SOURCE, "models", "obstacles-random.safetensors")
    n = 24
    runs, info, poses, goals, logits = run_both_ways(tmp_path, world, model, n=n, seed=5)
    blocked = sum(s.get("blocked", False) for run in runs for s in run["steps"])
    assert blocked < n * 2.5  # the rule at work: mnist.safetensors ends about 5 of 20 moves against a box
    for i, run in enumerate(runs):
        assert list(poses[0, i]) == run["start"]
        assert [list(p) for p in poses[1:, i]] == [s["grid_pose"] for s in run["steps"]]
        assert [list(g) for g in goals[:, i]] == [s["goal"] for s in run["steps"]]
        assert int(np.argmax(logits[i])) == run["prediction"]


def test_the_agent_runs_in_the_precision_asked_for_as_scout_run_does(tmp_path):
    # The model was trained in bf16; fp32 asked for runs fp32 and chooses what `scout run
    # --precision fp32` chooses: the same digits, starts, moves, goals and probabilities.
    n, seed = 8, 4
    out = tmp_path / "run"
    subprocess.run([BINARY, "run", WORLD, "--checkpoint", MODEL, "--precision", "fp32", "--seed", str(seed),
                    "--count", str(n), "--no-images", "--out", str(out)], check=True, capture_output=True)
    runs = json.loads((out / "trajectory.json").read_text())["runs"]
    agent = scout.Agent(MODEL, precision="fp32")
    assert (agent.precision, agent.trained_precision) == ("fp32", "bf16")
    info, poses, goals, logits = drive(scout.make_vec(WORLD, n, seed=seed), agent, seed)
    for i, run in enumerate(runs):
        assert (info["index"][i], info["label"][i]) == (run["index"], run["label"])
        assert list(poses[0, i]) == run["start"]
        assert [list(p) for p in poses[1:, i]] == [s["grid_pose"] for s in run["steps"]]
        assert [list(g) for g in goals[:, i]] == [s["goal"] for s in run["steps"]]
        assert np.allclose(np.exp(logits[i]), run["probabilities"], atol=1e-6)
        assert int(np.argmax(logits[i])) == run["prediction"]
    # The comparison tells the precisions apart: in bf16 the classifier's probabilities differ from
    # fp32's by far more than the 1e-6 above, so an Agent that ran bf16 whatever it was asked for
    # would fail the loop.
    envs = scout.make_vec(WORLD, n, seed=seed)
    obs, _ = envs.reset()
    obs, *_ = envs.step({"move": np.arange(n) % 4})
    bf16 = scout.Agent(MODEL, precision="bf16")
    assert bf16.precision == "bf16"
    assert np.abs(np.exp(bf16.classify(obs)) - np.exp(agent.classify(obs))).max() > 1e-3
    with pytest.raises(ValueError) as caught:
        scout.Agent(MODEL, precision="fp16")
    assert str(caught.value) == 'precision: expected one of fp32, bf16, auto, got "fp16"'


def cpu_has_native_bf16():
    """What /proc/cpuinfo says, read independently of Scout's CPUID check."""
    with open("/proc/cpuinfo") as f:
        flags = next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), [])
    return "avx512_bf16" in flags or "amx_bf16" in flags


AUTO_PROBE = """
import json, sys, numpy as np, scout
envs = scout.make_vec(%r, 4, seed=2)
obs, _ = envs.reset()
obs, *_ = envs.step({"move": np.array([0, 1, 2, 3])})
auto = scout.Agent(%r)
resolved = scout.Agent(%r, precision=auto.precision)
same_output = np.array_equal(auto.classify(obs), resolved.classify(obs))
print(json.dumps([auto.precision, auto.trained_precision, bool(same_output)]))
"""


@pytest.mark.parametrize("capped", [True, False], ids=["avx2-cap", "this-cpu"])
def test_the_agents_auto_precision_is_bf16_only_where_bf16_is_native_and_faster(capped):
    # oneDNN capped to AVX2: the stand-in for a CPU without native bf16, where auto is fp32;
    # uncapped, auto is fp32 where /proc/cpuinfo shows neither AVX-512 BF16 nor AMX-BF16, and where
    # it shows one, what the measurement cached for this CPU chose (learn/auto_precision.hpp). Either
    # way the agent runs what it says: its classifier's output is that of an agent asked for it.
    env = dict(os.environ)
    if capped:
        env.update(ONEDNN_MAX_CPU_ISA="AVX2", ATEN_CPU_CAPABILITY="avx2")
    else:
        for name in ("ONEDNN_MAX_CPU_ISA", "DNNL_MAX_CPU_ISA", "ATEN_CPU_CAPABILITY"):
            env.pop(name, None)
    result = subprocess.run([sys.executable, "-c", AUTO_PROBE % (WORLD, MODEL, MODEL)], env=env, capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stderr
    precision, trained, same_output = json.loads(result.stdout)
    expected = "fp32" if capped or not cpu_has_native_bf16() else measured_auto_precision()
    assert (precision, trained, same_output) == (expected, "bf16", True)


def measured_auto_precision():
    """What the cached measurement chose for this CPU without a cap (learn/auto_precision.hpp)."""
    folder = os.environ.get("SCOUT_CACHE_DIR") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "scout")
    with open(os.path.join(folder, "precision.json")) as f:
        choices = json.load(f)["choices"]
    uncapped = {entry["precision"] for key, entry in choices.items()
                if "MAX_CPU_ISA" not in key and "ATEN_CPU_CAPABILITY" not in key}
    assert len(uncapped) == 1, choices  # one CPU, one LibTorch
    return uncapped.pop()


def first_goals(agent, obs, info, shift):
    """The goals the agent chooses at the start of the runs, shown policy seeds shifted by `shift`."""
    return agent.act(obs, dict(info, policy_seed=info["policy_seed"] + np.uint64(shift)))["goal"]


def test_the_greedy_agent_is_scout_run_greedy_and_ignores_the_policy_seeds(tmp_path):
    # greedy=True: argmax goals and moves, as `scout run --greedy` chooses them, whatever the runs'
    # policy seeds; greedy=False samples from those seeds, so other seeds choose other goals.
    n, seed = 6, 9
    out = tmp_path / "run"
    subprocess.run([BINARY, "run", WORLD, "--checkpoint", MODEL, "--greedy", "--seed", str(seed), "--count", str(n),
                    "--no-images", "--out", str(out)], check=True, capture_output=True)
    runs = json.loads((out / "trajectory.json").read_text())["runs"]
    greedy = scout.Agent(MODEL, greedy=True, threads=1)
    _, poses, goals, logits = drive(scout.make_vec(WORLD, n, seed=seed), greedy, seed)
    for i, run in enumerate(runs):
        assert [list(p) for p in poses[1:, i]] == [s["grid_pose"] for s in run["steps"]]
        assert [list(g) for g in goals[:, i]] == [s["goal"] for s in run["steps"]]
        assert np.allclose(np.exp(logits[i]), run["probabilities"], atol=1e-6)
    obs, info = scout.make_vec(WORLD, n, seed=seed).reset()
    assert np.array_equal(first_goals(greedy, obs, info, 12345), goals[0])
    sampling = scout.Agent(MODEL, threads=1)
    sampled = first_goals(sampling, obs, info, 0)
    assert np.array_equal(first_goals(sampling, obs, info, 0), sampled)  # the same seeds choose the same
    assert not np.array_equal(first_goals(sampling, obs, info, 12345), sampled)
    assert not np.array_equal(sampled, goals[0])


THREADS_PROBE = """
import json, os, numpy as np, scout
import scout._scout_agent  # LibTorch loaded first: threads a library starts as it loads are not the networks'
import torch  # the environment's, over the same libtorch_cpu: it reads the setting scout.Agent makes
envs = scout.make_vec(%r, 16, seed=1)
obs, info = envs.reset()
def threads(): return len(os.listdir("/proc/self/task"))
seen = []
for asked in (1, 3, 0):
    before = threads()
    agent = scout.Agent(%r, threads=asked)
    agent.classify(obs)
    agent.act(obs, info)
    seen.append([asked, torch.get_num_threads(), threads() - before])
libraries = {os.path.realpath(line.split()[-1]) for line in open("/proc/self/maps") if "libtorch_cpu" in line}
assert len(libraries) == 1, libraries  # one LibTorch: torch.get_num_threads() is scout.Agent's
print(json.dumps(seen))
"""


def test_the_agents_threads_are_the_ones_asked_for():
    # LibTorch's intra-op threads: with 1 the networks run on the calling thread alone (they start
    # no thread), with 3 on at least two more, with 0 one per core.
    result = subprocess.run([sys.executable, "-c", THREADS_PROBE % (WORLD, MODEL)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    one, three, zero = json.loads(result.stdout)  # [asked, LibTorch's setting, threads started]
    assert one[1:] == [1, 0], one
    assert three[1] == 3 and three[2] >= 2, three
    assert zero[1] == os.cpu_count(), zero


@pytest.fixture(scope="module")
def agent_and_robots():
    """An agent, 3 robots at the start of their runs and what the agent chooses for them."""
    agent = scout.Agent(MODEL, threads=1)
    obs, info = scout.make_vec(WORLD, 3, seed=1).reset()
    return agent, obs, info, agent.act(obs, info), agent.classify(obs)


@pytest.mark.parametrize("kwargs, error, message", [
    ({"model": 123}, TypeError, "model: expected a path to a model file or run folder, got 123"),
    ({"model": "/no/such.safetensors"}, ValueError, "/no/such.safetensors: no such checkpoint file"),
    ({"model": os.path.join(SOURCE, "README.md")}, ValueError,
     f"{os.path.join(SOURCE, 'README.md')}: not a valid safetensors file"),
    ({"greedy": "no"}, TypeError, "greedy: expected True or False, got 'no'"),
    ({"greedy": None}, TypeError, "greedy: expected True or False, got None"),
    ({"threads": -1}, ValueError, "threads: expected an integer in 0..256 (0: one per core), got -1"),
    ({"threads": 257}, ValueError, "threads: expected an integer in 0..256 (0: one per core), got 257"),
    ({"threads": 1.5}, ValueError, "threads: expected an integer in 0..256 (0: one per core), got 1.5"),
    ({"threads": True}, ValueError, "threads: expected an integer in 0..256 (0: one per core), got True"),
    ({"precision": "fp16"}, ValueError, 'precision: expected one of fp32, bf16, auto, got "fp16"'),
    ({"precision": None}, TypeError, "precision: expected 'auto', 'bf16' or 'fp32', got None"),
])
def test_bad_agent_arguments_raise_one_clear_line(kwargs, error, message):
    args = dict({"model": MODEL}, **kwargs)
    with pytest.raises(error) as caught:
        scout.Agent(**args)
    text = str(caught.value)
    assert "\n" not in text
    assert text.startswith(message), text


def changed(source, **entries):
    """A copy of obs or info with entries replaced (None: removed)."""
    copy = dict(source, **entries)
    return {k: v for k, v in copy.items() if v is not None}


@pytest.mark.parametrize("call, error, message", [
    (lambda o, i: ("act", None, i), TypeError, "obs: expected the dict make_vec's reset and step return, got NoneType"),
    (lambda o, i: ("act", o, None), TypeError,
     "info: expected the dict make_vec's reset and step return, got NoneType"),
    (lambda o, i: ("classify", [o], None), TypeError,
     "obs: expected the dict make_vec's reset and step return, got list"),
    (lambda o, i: ("act", changed(o, pose=None), i), ValueError, "obs['pose']: missing"),
    (lambda o, i: ("act", changed(o, pose=o["pose"][:2]), i), ValueError,
     "obs['pose']: expected shape (3, 2), got (2, 2)"),
    (lambda o, i: ("act", changed(o, pose=o["pose"] + 0.5), i), TypeError,
     "obs['pose']: expected integers, got dtype float64"),
    (lambda o, i: ("act", changed(o, pose=o["pose"].astype(np.int64) + 2**32), i), ValueError,
     "obs['pose']: expected values that fit int32, got 42949"),
    (lambda o, i: ("act", changed(o, pose=o["pose"] + 100), i), ValueError,
     "obs['pose'][0]: expected a cell of the floor"),
    (lambda o, i: ("act", changed(o, seen=o["seen"][0]), i), ValueError,
     "obs['seen']: expected shape (num_envs, H, W)"),
    (lambda o, i: ("act", changed(o, seen=o["seen"] * 0.5), i), TypeError,
     "obs['seen']: expected integers, got dtype float64"),
    (lambda o, i: ("act", changed(o, patch=None), i), ValueError, "obs['patch']: expected shape (3, m, m), got (0,)"),
    (lambda o, i: ("act", changed(o, revealed=o["revealed"][:, :5]), i), ValueError,
     "obs['revealed']: expected shape (3, 28, 28), got (3, 5, 28)"),
    (lambda o, i: ("classify", changed(o, revealed=np.full_like(o["revealed"], np.nan)), None), ValueError,
     "obs['revealed']: expected values in [0, 1] (the floor's pixels / 255), got nan"),
    (lambda o, i: ("classify", changed(o, revealed=o["revealed"] - 1), None), ValueError,
     "obs['revealed']: expected values in [0, 1] (the floor's pixels / 255), got -1.0"),
    (lambda o, i: ("act", changed(o, time_step=None), i), ValueError, "obs['time_step']: missing"),
    (lambda o, i: ("act", changed(o, time_step=np.array([0, 1, 0])), i), ValueError,
     "scout.Agent: every robot must be at the same move of its episode (time_step 0 and 1)"),
    (lambda o, i: ("act", o, changed(i, policy_seed=None)), ValueError, "info['policy_seed']: missing"),
    (lambda o, i: ("act", o, changed(i, policy_seed=-np.ones(3, np.int64))), ValueError,
     "info['policy_seed']: expected values that fit uint64, got -1"),
    (lambda o, i: ("act", o, changed(i, goal_episode=np.zeros(2, np.int32))), ValueError,
     "info['goal_episode']: expected shape (3,), got (2,)"),
])
def test_bad_agent_inputs_raise_one_clear_line_and_change_nothing(agent_and_robots, call, error, message):
    agent, obs, info, action, logits = agent_and_robots
    method, bad_obs, bad_info = call(obs, info)
    with pytest.raises(error) as caught:
        getattr(agent, method)(*([bad_obs, bad_info] if method == "act" else [bad_obs]))
    text = str(caught.value)
    assert "\n" not in text
    assert text.startswith(message), text
    # The agent was left as it was: it chooses and classifies what it did before the refusal.
    again = agent.act(obs, info)
    assert all(np.array_equal(again[k], action[k]) for k in action)
    assert np.array_equal(agent.classify(obs), logits)


def test_an_agent_must_see_the_runs_start():
    agent = scout.Agent(MODEL, threads=1)
    envs = scout.make_vec(WORLD, 2, seed=1)
    envs.reset()
    obs, _, _, _, info = envs.step({"move": np.zeros(2, int)})
    with pytest.raises(ValueError) as caught:
        agent.act(obs, info)
    assert str(caught.value) == "scout.Agent: act() must first see the robots at time_step 0 (after reset)"


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


def read_idx(path):
    """An IDX file as a NumPy array, read here without Scout: big-endian dimensions after the magic."""
    raw = np.fromfile(path, np.uint8)
    assert raw[0] == raw[1] == 0 and raw[2] == 8, path  # unsigned bytes
    dims = raw[3]
    shape = tuple(int(d) for d in raw[4:4 + 4 * dims].view(">u4"))
    return raw[4 + 4 * dims:].reshape(shape)


SUBSET = os.path.join(SOURCE, "tests", "data", "mnist-subset")  # 96 train, 32 validation, 64 test digits


@pytest.mark.parametrize("split, files", [("train", "train"), ("validation", "validation"), ("test", "t10k"),
                                          (None, "t10k")])  # None: the world's own split (test)
def test_split_and_data_pick_that_splits_digits(split, files):
    images = read_idx(os.path.join(SUBSET, f"{files}-images-idx3-ubyte"))
    labels = read_idx(os.path.join(SUBSET, f"{files}-labels-idx1-ubyte"))
    n = len(labels)
    # As many robots as digits: the first runs take every digit of the split once (a permutation).
    envs = scout.make_vec(WORLD, n, seed=3, split=split, data=SUBSET)
    obs, info = envs.reset()
    assert sorted(info["index"]) == list(range(n))
    assert np.array_equal(info["label"], labels[info["index"]])
    seen = obs["seen"] == 1
    assert seen.any(axis=(1, 2)).all()
    floors = images[info["index"]]  # revealed is the floor's bytes / 255 where seen
    assert np.array_equal(np.rint(obs["revealed"][seen] * 255), floors[seen]), "the floor seen is not the split's digit"
    # One robot (scout.Env) takes the same keywords: reset(seed=3) runs make_vec's robot 0's run.
    env = scout.Env(WORLD, split=split, data=SUBSET)
    one, one_info = env.reset(seed=3)
    assert (one_info["index"], one_info["label"]) == (info["index"][0], info["label"][0])
    assert np.array_equal(one["revealed"], obs["revealed"][0])


def test_split_without_data_reads_the_installed_mnist():
    # data=None: the installed MNIST (data/mnist, or $SCOUT_DATA/mnist), whose validation split is
    # its own file pair.
    images = read_idx(os.path.join(DATA, "validation-images-idx3-ubyte"))
    labels = read_idx(os.path.join(DATA, "validation-labels-idx1-ubyte"))
    obs, info = scout.make_vec(WORLD, 8, seed=3, split="validation").reset()
    assert np.array_equal(info["label"], labels[info["index"]])
    seen = obs["seen"] == 1
    assert np.array_equal(np.rint(obs["revealed"][seen] * 255), images[info["index"]][seen])


def test_a_missing_or_incomplete_data_folder_is_one_clear_line(tmp_path):
    expected = ("expected train-images-idx3-ubyte, train-labels-idx1-ubyte, t10k-images-idx3-ubyte, "
                "t10k-labels-idx1-ubyte")
    (tmp_path / "mnist").mkdir()
    for name in os.listdir(SUBSET):
        if name != "t10k-labels-idx1-ubyte":
            os.symlink(os.path.join(SUBSET, name), tmp_path / "mnist" / name)
    cases = [({"data": "/no/such/folder"}, ValueError, f"{WORLD}:3: floor.dataset: /no/such/folder/mnist: no such "
              "folder; " + expected, "(run `scout data --data /no/such/folder` to install MNIST there)"),
             ({"data": str(tmp_path)}, ValueError, f"{WORLD}:3: floor.dataset: {tmp_path}/mnist: missing "
              "t10k-labels-idx1-ubyte[.gz]; " + expected, ""),
             ({"data": ""}, ValueError, "data: expected a path to a data folder, got ''", ""),
             ({"data": 5}, TypeError, "data: expected a path to a data folder, got 5", ""),
             ({"split": "Test"}, ValueError, "split: expected 'train', 'validation' or 'test', got 'Test'", ""),
             ({"split": 1}, ValueError, "split: expected 'train', 'validation' or 'test', got 1", "")]
    for kwargs, error, starts, ends in cases:
        for make in (lambda: scout.make_vec(WORLD, 2, **kwargs), lambda: scout.Env(WORLD, **kwargs)):
            with pytest.raises(error) as caught:
                make()
            text = str(caught.value)
            assert "\n" not in text and text.startswith(starts) and text.endswith(ends), (kwargs, text)
    # The folder serves the splits it has: train needs no t10k labels.
    _, info = scout.make_vec(WORLD, 96, seed=1, split="train", data=str(tmp_path)).reset()
    assert sorted(info["index"]) == list(range(96))


def test_close_and_the_with_statement_release_the_environment():
    step = {"move": np.zeros(2, int)}
    with scout.make_vec(WORLD, 2, seed=1, render_mode="rgb_array") as envs:
        assert not envs.closed
        core = weakref.ref(envs._core)
        envs.reset()
        envs.step(step)
    assert envs.closed
    gc.collect()
    assert core() is None, "close() kept the C++ environment (its robots, floors and threads) alive"
    for what, call in (("reset", envs.reset), ("step", lambda: envs.step(step)), ("render", envs.render)):
        with pytest.raises(ValueError) as caught:
            call()
        assert str(caught.value) == f"{what}: the environment is closed"
    envs.close()  # a second close is harmless
    assert envs.closed
    # An exception inside the block still closes, and goes on up.
    with pytest.raises(KeyError, match="inside"):
        with scout.make_vec(WORLD, 2) as inner:
            raise KeyError("inside")
    assert inner.closed
    # One robot: the same, with or without Gymnasium (gymnasium.Env's with-statement).
    with scout.Env(WORLD) as env:
        env.reset(seed=1)
    assert env.closed
    with pytest.raises(ValueError) as caught:
        env.step({"move": 0})
    assert str(caught.value) == "step: the environment is closed"
    env.close()
    assert env.closed


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


OBSTACLES_WORLD = os.path.join(SOURCE, "worlds", "scenarios", "obstacles-random.yaml")


def grown_model(world, run, channel, images):
    """MODEL grown into a channel (--occupancy, --wide-view) and trained a few steps in `world`, so
    that the channel's weights move off zero: the checkpoint's path."""
    subprocess.run([BINARY, "train", world, "--out", str(run), "--init-from", MODEL, channel, "--epochs", "0,0,1",
                    "--train-limit", str(images), "--validation-limit", "20", "--batch", "20", "--lr", "0.01",
                    "--threads", "1", "--seed", "4"], check=True, capture_output=True)
    return str(run / "checkpoint.safetensors")


def test_a_world_with_obstacles_observes_o_and_the_agent_reads_it_as_scout_run_does(tmp_path):
    # A model with the occupancy channel, its o-weights moved off zero by a few steps in the world.
    model = grown_model(OBSTACLES_WORLD, tmp_path / "occupancy", "--occupancy", 80)
    n, seed = 24, 9
    envs = scout.make_vec(OBSTACLES_WORLD, n, seed=seed)
    obs, info = envs.reset(seed=seed)
    assert envs.observation_space.contains(obs)
    assert obs["occupied"].shape == (n, 28, 28) and obs["occupied"].dtype == np.uint8
    # Each run its own boxes (three of 2-4 px, widened by the robot's radius): o differs by robot.
    assert len({o.tobytes() for o in obs["occupied"]}) == n
    assert all(9 <= o.sum() <= 28 * 28 // 2 for o in obs["occupied"])
    assert "occupied" not in scout.make_vec(WORLD, 2, seed=1).reset()[0]

    out = tmp_path / "run"
    subprocess.run([BINARY, "run", OBSTACLES_WORLD, "--checkpoint", model, "--seed", str(seed), "--count", str(n),
                    "--no-images", "--out", str(out)], check=True, capture_output=True)
    runs = json.loads((out / "trajectory.json").read_text())["runs"]
    _, poses, goals, _ = drive(envs, scout.Agent(model), seed)
    for i, r in enumerate(runs):
        assert list(poses[0, i]) == r["start"]
        assert [list(p) for p in poses[1:, i]] == [s["grid_pose"] for s in r["steps"]], f"robot {i}"
        assert [list(g) for g in goals[:, i]] == [s["goal"] for s in r["steps"]], f"robot {i}"
    # Without o the same agent chooses otherwise: it reads the channel.
    agent = scout.Agent(model)
    obs, info = envs.reset(seed=seed)
    with_o = agent.act(obs, info)["goal"]
    blind = agent.act({k: v for k, v in obs.items() if k != "occupied"}, info)["goal"]
    assert not np.array_equal(with_o, blind)


TEAM_WORLD = os.path.join(SOURCE, "worlds", "scenarios", "team-2.yaml")


def window_union(poses, m=6, side=28):
    """h as the camera windows of `poses` (any number of (x, y)) reveal it."""
    seen = np.zeros((side, side), np.uint8)
    for x, y in poses:
        seen[max(y - m // 2, 0):min(y - m // 2 + m, side), max(x - m // 2, 0):min(x - m // 2 + m, side)] = 1
    return seen


def test_a_team_world_has_k_robots_per_environment_sharing_what_they_have_seen(tmp_path):
    # team-2.yaml: two robots per environment, each E / K = 2 episodes of T = 5 moves.
    n, seed = 5, 3
    envs = scout.make_vec(TEAM_WORLD, n, seed=seed)
    obs, info = envs.reset(seed=seed)
    assert envs.observation_space.contains(obs)
    assert obs["patch"].shape == (n, 2, 6, 6) and obs["pose"].shape == (n, 2, 2)
    assert obs["revealed"].shape == (n, 28, 28) and obs["seen"].shape == (n, 28, 28)
    assert info["pose_m"].shape == (n, 2, 2)
    # The runs are `scout run`'s: the same digits, and the team's starts (a diameter apart).
    out = tmp_path / "run"
    subprocess.run([BINARY, "run", TEAM_WORLD, "--seed", str(seed), "--count", str(n), "--no-images", "--out",
                    str(out)], check=True, capture_output=True)
    runs = json.loads((out / "trajectory.json").read_text())["runs"]
    for i, run in enumerate(runs):
        assert info["index"][i] == run["index"]
        assert [list(obs["pose"][i, 0]), list(obs["pose"][i, 1])] == [run["start"], run["teammates"][0]["start"]]
        assert np.linalg.norm(obs["pose"][i, 0] - obs["pose"][i, 1]) > 5.0
    rng = np.random.default_rng(0)
    history = [[tuple(p) for p in obs["pose"][i]] for i in range(n)]
    for step in range(10):
        moves = rng.integers(0, 4, size=(n, 2), dtype=np.int32)
        obs, reward, terminated, truncated, info = envs.step({"move": moves})
        for i in range(n):
            history[i] += [tuple(p) for p in obs["pose"][i]]
            # h is the union of both robots' windows over the run; y is 0 where unseen.
            assert np.array_equal(obs["seen"][i], window_union(history[i])), (step, i)
            assert not obs["revealed"][i][obs["seen"][i] == 0].any()
        assert obs["time_step"].tolist() == [step + 1] * n
        assert terminated.all() == (step == 9)
    with pytest.raises(ValueError, match=r"move"):
        envs.step({"move": np.zeros(n, np.int32)})  # one move per environment, not per robot
    single = scout.Env(TEAM_WORLD)
    obs, _ = single.reset(seed=seed)
    assert obs["patch"].shape == (2, 6, 6)
    obs, *_ = single.step({"move": np.array([0, 2])})
    assert obs["pose"].shape == (2, 2)
    with pytest.raises(ValueError, match="teams of 2 robots"):
        scout.Agent(MODEL).act(*envs.reset(seed=seed))


TRANSLATED_WORLD = os.path.join(SOURCE, "worlds", "translated-60.yaml")


def test_the_wider_view_is_observed_and_a_wide_view_agent_reads_it_as_scout_run_does(tmp_path):
    # A model whose planners read the wider view (--wide-view), its y_w and h_w weights moved off
    # zero by a few steps in the 60 x 60 translated world (8 x 8 coarse pixels of 6 x 6).
    model = grown_model(TRANSLATED_WORLD, tmp_path / "wide", "--wide-view", 40)
    n, seed, side, wide, scale = 12, 5, 60, 8, 6
    envs = scout.make_vec(TRANSLATED_WORLD, n, seed=seed)
    obs, info = envs.reset(seed=seed)
    assert envs.observation_space.contains(obs)
    assert obs["wide_patch"].shape == (n, wide, wide) and obs["wide_seen"].shape == (n, side, side)
    # What the coarse map holds: each look's window of 48 x 48 floor pixels, the 8 x 8 blocks of
    # the floor's grid from the robot's block less 4, clipped to the floor, painted block by block
    # with the look's coarse pixels.
    for step in range(3):
        for i in range(n):
            x0, y0 = (obs["pose"][i] // scale - wide // 2) * scale
            block = np.kron(obs["wide_patch"][i], np.ones((scale, scale), np.float32))
            ys, xs = slice(max(y0, 0), min(y0 + wide * scale, side)), slice(max(x0, 0), min(x0 + wide * scale, side))
            window = block[ys.start - y0:ys.stop - y0, xs.start - x0:xs.stop - x0]
            assert np.array_equal(obs["wide_revealed"][i][ys, xs], window), f"robot {i}, move {step}"
            assert obs["wide_seen"][i][ys, xs].all()
            if step == 0:  # nothing else is set yet
                assert obs["wide_seen"][i].sum() == window.size
        seen_before = obs["wide_seen"].copy()
        obs, *_ = envs.step({"move": np.full(n, step % 4)})
        assert np.all(obs["wide_seen"] >= seen_before)  # the map only grows
    assert "wide_patch" not in scout.make_vec(WORLD, 2, seed=1).reset()[0]

    # The agent chooses what `scout run` chooses with the same model and seed.
    out = tmp_path / "run"
    subprocess.run([BINARY, "run", TRANSLATED_WORLD, "--checkpoint", model, "--seed", str(seed), "--count", str(n),
                    "--no-images", "--out", str(out)], check=True, capture_output=True)
    runs = json.loads((out / "trajectory.json").read_text())["runs"]
    agent = scout.Agent(model)
    _, poses, goals, _ = drive(envs, agent, seed)
    for i, r in enumerate(runs):
        assert list(poses[0, i]) == r["start"]
        assert [list(g) for g in goals[:, i]] == [s["goal"] for s in r["steps"]], f"robot {i}"
    # It reads the coarse map: without what it shows, it chooses otherwise; without the keys, one line.
    obs, info = envs.reset(seed=seed)
    blind = dict(obs, wide_revealed=np.zeros_like(obs["wide_revealed"]), wide_seen=np.zeros_like(obs["wide_seen"]))
    assert not np.array_equal(agent.act(obs, info)["goal"], agent.act(blind, info)["goal"])
    with pytest.raises(ValueError, match=r"planners read the wider view \(--wide-view\): expected obs\['wide_revealed'\]"):
        agent.act({k: v for k, v in obs.items() if not k.startswith("wide_")}, info)
    # A map not laid on the model's 6 x 6 blocks (here shifted a pixel) would be read misaligned: refused.
    shifted = dict(obs, wide_seen=np.roll(obs["wide_seen"], 1, axis=2))
    with pytest.raises(ValueError, match=r"expected each map constant on the model's 6 x 6 blocks"):
        agent.act(shifted, info)


def test_models_and_checkpoints_are_safetensors_files_both_ways(tmp_path):
    """Scout's files open with the `safetensors` package (NumPy side) with the names, shapes and
    values Scout's own reader loads; a model edited and written by that package loads in Scout and
    drives with the edit."""
    from safetensors import safe_open
    from safetensors.numpy import load_file, save_file
    run = tmp_path / "run"
    subprocess.run([BINARY, "train", WORLD, "--out", str(run), "--init-from", MODEL, "--epochs", "0,0,1",
                    "--train-limit", "40", "--validation-limit", "20", "--batch", "20", "--threads", "1"],
                   check=True, capture_output=True)
    checkpoint = run / "checkpoint.safetensors"
    for path, with_adam in [(MODEL, False), (os.path.join(SOURCE, "models", "mnist.safetensors"), False),
                            (checkpoint, True)]:
        theirs, ours = load_file(str(path)), scout.checkpoint_tensors(path)
        assert sorted(theirs) == sorted(ours), path
        for name, value in theirs.items():
            assert value.dtype == ours[name].dtype and value.shape == ours[name].shape, name
            assert np.array_equal(value, ours[name]), name
        assert any(name.endswith(".exp_avg_sq") for name in theirs) == with_adam, path
        with safe_open(str(path), "np") as f:
            metadata = f.metadata()
        assert metadata["format"] == "scout-checkpoint" and metadata["format_version"] == "2"
        assert json.loads(metadata["config"])["network"]["classes"] == 10
    assert json.loads(metadata["progress"])["history"], "the checkpoint's epochs"
    assert all(v >= 1 for k, v in theirs.items() if k.endswith(".step"))

    # Edited in Python: the classifier's last bias made to favour class 3 by far. Scout reads the
    # edit, and the agent then calls every digit a 3.
    weights = load_file(MODEL)
    with safe_open(MODEL, "np") as f:
        metadata = f.metadata()
    last = "agent.classifier.head.bias"  # the classifier's output layer: one bias per class
    assert weights[last].shape == (10,)
    weights[last] = weights[last].copy()
    weights[last][3] += 1000.0
    edited = tmp_path / "edited.safetensors"
    save_file(weights, str(edited), metadata=metadata)
    assert np.array_equal(scout.checkpoint_tensors(edited)[last], weights[last])
    envs = scout.make_vec(WORLD, 16, seed=3)
    edited_logits = drive(envs, scout.Agent(edited), 3)[3]
    logits = drive(envs, scout.Agent(MODEL), 3)[3]
    assert (edited_logits.argmax(axis=1) == 3).all()
    assert (logits.argmax(axis=1) != 3).any()
    # A tensor dropped in Python: one clear error naming the file and the tensor.
    del weights[last]
    save_file(weights, str(tmp_path / "short.safetensors"), metadata=metadata)
    with pytest.raises(ValueError, match=r"short\.safetensors.*" + last.replace(".", r"\.") + " is missing"):
        scout.checkpoint_tensors(tmp_path / "short.safetensors")
