"""Scout inside the real Gymnasium (1.4.0, from PyPI in the project's .venv): make_vec
is a gymnasium.vector.VectorEnv, the registered ids, check_env, the standard wrappers, SyncVectorEnv
over single envs against make_vec, the spaces utilities, the autoreset modes, rendering; and the
package without Gymnasium. ctest runs this on the project's Python (.venv, where
scripts/setup.sh installs Gymnasium); where Gymnasium cannot be imported the module is skipped with
one line, except under CI (CI=true), where that fails it."""
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest
from gymnasium_missing import skip_or_fail

try:
    import gymnasium
    from gymnasium.utils.env_checker import check_env
    from gymnasium.vector import AutoresetMode
except ImportError as error:
    skip_or_fail(error, module=True)

import scout

SOURCE = os.environ.get("SCOUT_SOURCE_DIR", os.path.dirname(os.path.dirname(os.path.dirname(__file__))))
WORLD = os.path.join(SOURCE, "worlds", "mnist.yaml")
RUN = 20  # E x T moves of worlds/mnist.yaml


def logits_for(labels, classes=10):
    """Logits for the right label, more confident robot by robot: rewards that differ."""
    logits = np.zeros((len(labels), classes), np.float32)
    logits[np.arange(len(labels)), labels] = 1.0 + 0.5 * np.arange(len(labels))
    return logits


def test_make_vec_is_a_gymnasium_vector_env():
    envs = scout.make_vec(WORLD, 5, seed=3)
    assert isinstance(envs, gymnasium.vector.VectorEnv)
    assert envs.metadata["autoreset_mode"] is AutoresetMode.NEXT_STEP
    assert envs.render_mode is None and envs.unwrapped is envs and not envs.closed
    assert isinstance(envs.single_observation_space, gymnasium.spaces.Dict)
    assert isinstance(envs.single_observation_space["patch"], gymnasium.spaces.Box)
    assert envs.observation_space == gymnasium.vector.utils.batch_space(envs.single_observation_space, 5)
    assert envs.action_space == gymnasium.vector.utils.batch_space(envs.single_action_space, 5)
    obs, info = envs.reset(seed=7)
    assert obs in envs.observation_space
    assert envs.np_random_seed == 7
    first = envs.np_random.integers(1 << 30)
    envs.reset(seed=7)
    assert envs.np_random.integers(1 << 30) == first
    obs, reward, terminated, truncated, info = envs.step({"move": np.zeros(5, int)})
    assert obs in envs.observation_space
    assert reward.shape == (5,) and terminated.dtype == np.bool_ and truncated.dtype == np.bool_
    assert "episode" not in info and "_episode" not in info, "RecordEpisodeStatistics owns those keys"
    assert {"goal_episode", "goal_episode_start", "label", "index", "pose_m", "policy_seed"} <= set(info)
    envs.close()
    assert envs.closed
    with pytest.raises(ValueError, match="^step: the environment is closed$"):
        envs.step({"move": np.zeros(5, int)})
    envs.close()  # twice is fine


def test_the_with_statement_closes_through_gymnasium():
    # gymnasium.vector.VectorEnv has no with-statement of its own: scout.VectorEnv's closes it;
    # gymnasium.make's wrappers pass close() down to scout.Env.
    with gymnasium.make_vec("scout/MNIST-v0", num_envs=2) as envs:
        envs.reset(seed=1)
    assert envs.closed and envs._core is None
    with pytest.raises(ValueError, match="^reset: the environment is closed$"):
        envs.reset()
    with gymnasium.make("scout/MNIST-v0") as env:
        env.reset(seed=1)
    assert env.unwrapped.closed
    with pytest.raises(ValueError, match="^reset: the environment is closed$"):
        env.unwrapped.reset()
    env.close()  # twice is fine


def test_registered_ids_make_the_vector_env_one_robot_and_any_world():
    envs = gymnasium.make_vec("scout/MNIST-v0", num_envs=4, seed=2)
    assert isinstance(envs, scout.VectorEnv) and envs.num_envs == 4
    assert envs.spec.id == "scout/MNIST-v0" and envs.spec.kwargs["num_envs"] == 4
    reference = scout.make_vec(WORLD, 4, seed=2)
    assert np.array_equal(envs.reset()[1]["index"], reference.reset()[1]["index"]), "the id is worlds/mnist.yaml"
    fixed = gymnasium.make_vec("scout/MNIST-v0", num_envs=3, world=os.path.join(SOURCE, "worlds", "digit-fixed.yaml"))
    _, info = fixed.reset(seed=1)
    assert len(set(info["index"].tolist())) == 1, "the world= keyword's fixed digit"
    env = gymnasium.make("scout/MNIST-v0")
    assert isinstance(env.unwrapped, scout.Env) and isinstance(env.unwrapped, gymnasium.Env)
    obs, _ = env.reset(seed=4)
    assert obs in env.observation_space and obs["patch"].shape == (6, 6)
    assert "scout/FashionMNIST-v0" in gymnasium.registry
    assert envs.spec.vector_entry_point == "scout:make_vec"


def test_the_single_env_passes_check_env():
    env = gymnasium.make("scout/MNIST-v0").unwrapped
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    # The only remarks: the prediction's logits are unbounded (any finite float32 is accepted).
    remarks = [str(w.message) for w in caught]
    assert all("Box action space" in r for r in remarks), remarks


def test_the_standard_wrapper_stack_records_the_runs_returns():
    n, seed = 6, 11
    raw = scout.make_vec(WORLD, n, seed=seed)
    envs = gymnasium.wrappers.vector.RecordEpisodeStatistics(scout.make_vec(WORLD, n, seed=seed))
    envs = gymnasium.wrappers.vector.ClipReward(envs, min_reward=-3.0, max_reward=0.0)
    envs = gymnasium.wrappers.vector.NormalizeReward(envs)
    envs = gymnasium.wrappers.vector.FlattenObservation(envs)
    envs = gymnasium.wrappers.vector.DictInfoToList(envs)
    obs, infos = envs.reset()
    _, raw_info = raw.reset()
    m, h, w = 6, 28, 28
    assert obs.shape == (n, m * m + 2 + h * w + h * w + 1)
    assert isinstance(infos, list) and len(infos) == n and infos[0]["label"] == raw_info["label"][0]
    rng = np.random.default_rng(0)
    returns, labels, recorded = np.zeros(n), raw_info["label"], []
    for t in range(2 * RUN + 2):
        action = {"move": rng.integers(0, 4, n), "prediction": logits_for(labels)}
        obs, reward, terminated, truncated, infos = envs.step(action)
        _, raw_reward, raw_terminated, _, raw_info = raw.step(action)
        assert np.array_equal(terminated, raw_terminated)
        assert np.all(np.isfinite(reward)) and np.all((reward != raw_reward) | (raw_reward == 0)), "normalized"
        returns += raw_reward
        for i in np.flatnonzero(terminated):
            recorded.append(infos[i]["episode"])
            assert infos[i]["episode"]["l"] == RUN
            assert infos[i]["episode"]["r"] == pytest.approx(returns[i], rel=1e-6)
        returns[terminated] = 0.0
        labels = raw_info["label"]
    assert len(recorded) == 2 * n
    assert envs.env.env.env.env.episode_count == 2 * n  # RecordEpisodeStatistics, under the others


def test_sync_vector_env_over_single_envs_is_make_vec_with_a_seed_per_robot():
    n, seed = 3, 5
    sync = gymnasium.make_vec("scout/MNIST-v0", num_envs=n, vectorization_mode="sync")
    vec = scout.make_vec(WORLD, n)
    assert sync.single_observation_space == vec.single_observation_space
    assert sync.observation_space == vec.observation_space
    assert sync.single_action_space == vec.single_action_space
    assert sync.action_space == vec.action_space
    # SyncVectorEnv seeds sub-env i with seed + i; make_vec's list gives robot i that seed.
    obs_s, info_s = sync.reset(seed=seed)
    obs_v, info_v = vec.reset(seed=[seed + i for i in range(n)])
    sync.action_space.seed(1)
    for t in range(2 * RUN + 3):  # through two autoresets
        for key in obs_v:
            assert np.array_equal(obs_s[key], obs_v[key]), (t, key)
        for key in ("label", "index", "policy_seed", "goal_episode"):
            assert np.array_equal(info_s[key], info_v[key]), (t, key)
        action = sync.action_space.sample()
        obs_s, reward_s, term_s, trunc_s, info_s = sync.step(action)
        obs_v, reward_v, term_v, trunc_v, info_v = vec.step(action)
        assert np.array_equal(term_s, term_v) and np.array_equal(trunc_s, trunc_v)
        assert np.allclose(reward_s, reward_v, atol=1e-6), t
    # One robot's seed s is `scout run --seed s`'s run 0, as make_vec(seed=s)'s robot 0.
    single = gymnasium.make("scout/MNIST-v0")
    _, info = single.reset(seed=seed)
    assert info["index"] == scout.make_vec(WORLD, 4, seed=seed).reset()[1]["index"][0]


def test_the_spaces_utilities():
    envs = scout.make_vec(WORLD, 4, seed=1)
    obs, _ = envs.reset()
    spaces = gymnasium.spaces
    flat = spaces.flatten_space(envs.single_observation_space)
    assert flat.shape == (6 * 6 + 2 + 28 * 28 * 2 + 1,)
    assert spaces.flatten_space(envs.observation_space).shape == (4 * flat.shape[0],)
    single = list(gymnasium.vector.utils.iterate(envs.observation_space, obs))
    assert len(single) == 4 and all(o in envs.single_observation_space for o in single)
    assert np.array_equal(single[2]["pose"], obs["pose"][2])
    assert spaces.flatten(envs.single_observation_space, single[0]) in flat
    patch_only = spaces.Dict({"patch": envs.single_observation_space["patch"]})
    assert {"patch": obs["patch"][0]} in patch_only
    actions = list(gymnasium.vector.utils.iterate(envs.action_space, {"move": np.array([0, 1, 2, 3])}))
    assert [a["move"] for a in actions] == [0, 1, 2, 3] and all(a in envs.single_action_space for a in actions)


def test_every_action_the_readme_shows_is_in_the_space_and_samples_step():
    envs = scout.make_vec(WORLD, 4, seed=2)
    obs, info = envs.reset()
    moves = np.zeros(4, int)
    assert {"move": moves} in envs.action_space
    assert {"move": moves, "prediction": np.zeros((4, 10), np.float32)} in envs.action_space
    assert {"move": moves, "goal": obs["pose"].astype(np.int64)} in envs.action_space
    assert {"prediction": np.zeros((4, 10), np.float32)} not in envs.action_space, "move is required"
    assert {"move": moves, "speed": 1} not in envs.action_space
    assert {"move": 1} in envs.single_action_space
    envs.action_space.seed(3)
    for _ in range(RUN + 2):
        action = envs.action_space.sample()
        assert set(action) == {"move", "prediction", "goal"}
        envs.step(action)


def test_same_step_autoreset_starts_the_next_run_at_once_and_keeps_the_last_observation():
    n = 3
    envs = scout.make_vec(WORLD, n, seed=9, autoreset_mode=AutoresetMode.SAME_STEP)
    next_step = scout.make_vec(WORLD, n, seed=9)
    assert envs.metadata["autoreset_mode"] is AutoresetMode.SAME_STEP
    stats = gymnasium.wrappers.vector.RecordEpisodeStatistics(envs)
    stats.reset()
    next_step.reset()
    moves = {"move": np.full(n, 2)}
    for t in range(1, RUN + 1):
        obs, reward, terminated, truncated, info = stats.step(moves)
        expected, *_, expected_info = next_step.step(moves)
        assert terminated.all() == (t == RUN)
    assert np.all(obs["time_step"] == 0), "the next run's first observation"
    assert info["_final_obs"].all() and info["_final_info"].all()
    for i in range(n):
        assert np.array_equal(info["final_obs"][i]["pose"], expected["pose"][i])
        assert info["final_obs"][i]["time_step"] == RUN
    assert np.array_equal(info["final_info"]["index"], expected_info["index"])
    assert np.array_equal(info["episode"]["l"], np.full(n, RUN))
    restarted, *_, restarted_info = next_step.step(moves)  # NEXT_STEP starts the same runs a step later
    assert np.array_equal(info["index"], restarted_info["index"])
    assert np.array_equal(obs["pose"], restarted["pose"])


def test_disabled_autoreset_waits_for_a_masked_reset():
    n = 3
    envs = scout.make_vec(WORLD, n, seed=4, autoreset_mode="Disabled")
    assert envs.metadata["autoreset_mode"] is AutoresetMode.DISABLED
    stats = gymnasium.wrappers.vector.RecordEpisodeStatistics(envs)
    stats.reset()
    for _ in range(RUN):
        obs, reward, terminated, *_ = stats.step({"move": np.zeros(n, int)})
    assert terminated.all()
    with pytest.raises(ValueError) as caught:
        stats.step({"move": np.zeros(n, int)})
    assert str(caught.value) == "step: robot 0's run has ended: reset it first (autoreset is off)"
    mask = np.array([True, False, True])
    options = {"reset_mask": mask}
    obs, info = stats.reset(options=options)
    assert "reset_mask" not in options, "RecordEpisodeStatistics read it after scout"
    assert list(obs["time_step"]) == [0, RUN, 0]
    with pytest.raises(ValueError, match="robot 1's run has ended"):
        stats.step({"move": np.zeros(n, int)})
    stats.reset(options={"reset_mask": np.array([False, True, False])})
    obs, *_ = stats.step({"move": np.zeros(n, int)})
    assert list(obs["time_step"]) == [1, 1, 1]
    with pytest.raises(TypeError, match="^reset_mask: expected a NumPy array of 3 booleans"):
        envs.reset(options={"reset_mask": [1, 0, 1]})
    with pytest.raises(ValueError, match="^options: expected None or"):
        envs.reset(options={"mask": mask})


def test_seeds_int_list_or_none():
    envs = scout.make_vec(WORLD, 3, seed=1)
    _, by_list = envs.reset(seed=[8, None, 30])
    for i, s in ((0, 8), (2, 30)):
        assert by_list["index"][i] == scout.make_vec(WORLD, 1).reset(seed=s)[1]["index"][0]
    with pytest.raises(ValueError, match=r"^seed: expected one seed or a list of 3 \(one per robot\), got a list of 2$"):
        envs.reset(seed=[1, 2])
    with pytest.raises(ValueError, match=r"^seed\[1\]: expected an integer in \[0, 2\*\*64\), got -4$"):
        envs.reset(seed=[1, -4, 2])
    with pytest.raises(TypeError, match="^seed: expected an integer"):
        envs.reset(seed=1.5)


def test_render_rgb_array_draws_each_robot():
    envs = scout.make_vec(WORLD, 2, seed=6, render_mode="rgb_array")
    envs.reset()
    before = envs.render()
    assert isinstance(before, tuple) and len(before) == 2
    assert before[0].shape == (280, 280, 3) and before[0].dtype == np.uint8
    assert not np.array_equal(before[0], before[1]), "two robots, two floors"
    envs.step({"move": np.array([0, 2])})
    after = envs.render()
    assert not np.array_equal(before[0], after[0]), "a move shows"
    with pytest.raises(ValueError, match="render_mode"):
        scout.make_vec(WORLD, 1).render()
    env = gymnasium.make("scout/MNIST-v0", render_mode="rgb_array")
    env.reset(seed=1)
    assert env.render().shape == (280, 280, 3)


def test_without_gymnasium_the_package_works_as_before():
    probe = ("import sys; sys.modules['gymnasium'] = None\n"
             "import numpy as np, scout\n"
             "envs = scout.make_vec(%r, 2, seed=1)\n"
             "assert type(envs).__mro__[1].__name__ == '_Base', type(envs).__mro__\n"
             "assert isinstance(envs.observation_space, scout.spaces.Dict)\n"
             "assert envs.metadata['autoreset_mode'] == 'NextStep'\n"
             "obs, info = envs.reset()\n"
             "assert obs in envs.observation_space and {'move': np.zeros(2, int)} in envs.action_space\n"
             "obs, reward, terminated, truncated, info = envs.step(envs.action_space.sample(np.random.default_rng(0)))\n"
             "print('ok', obs['time_step'].tolist())\n" % WORLD)
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["ok", "[1,", "1]"]


@pytest.mark.parametrize("env_id,side", [("scout/TranslatedMNIST60-v0", 60), ("scout/ClutteredMNIST60-v0", 60),
                                         ("scout/ClutteredMNIST100-v0", 100)])
def test_the_large_floor_ids_make_searching_tasks_that_gymnasium_accepts(env_id, side):
    # make_vec with the standard wrappers: the floor's size reaches the spaces, the digit lands
    # somewhere new in every run, and the runs' returns are recorded.
    envs = gymnasium.make_vec(env_id, num_envs=3, split="validation")
    assert envs.single_observation_space["revealed"].shape == (side, side)
    assert envs.single_observation_space["patch"].shape == (8, 8)
    assert envs.single_observation_space["wide_patch"].shape == (8, 8)
    envs = gymnasium.wrappers.vector.RecordEpisodeStatistics(envs)
    envs = gymnasium.wrappers.vector.FlattenObservation(envs)
    obs, info = envs.reset(seed=3)
    # patch, pose, revealed, seen, time step, then the wider view: its window, coarse map and mask
    assert obs.shape == (3, 8 * 8 + 2 + 2 * side * side + 1 + 8 * 8 + 2 * side * side)
    moves = 16  # 4 x 4 in these worlds
    rng = np.random.default_rng(1)
    episodes = 0
    for _ in range(moves):
        obs, reward, terminated, truncated, info = envs.step({"move": rng.integers(0, 4, 3),
                                                              "prediction": logits_for(info["label"])})
        episodes += int(terminated.sum())
    assert episodes == 3 and np.all(info["episode"]["l"][info["_episode"]] == moves)
    envs.close()
    # One robot passes Gymnasium's checker, and its picture shows the whole large floor.
    env = gymnasium.make(env_id, split="validation", render_mode="rgb_array").unwrapped
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env)
    assert all("Box action space" in str(w.message) for w in caught), [str(w.message) for w in caught]
    env.reset(seed=2)
    picture = env.render()
    assert picture.shape[0] == side * 10 and picture.shape[2] == 3
    env.close()
