"""``smartcar_gym.policy.Policy``: the shipped policies with their provenance's settings, actions
equal to SB3's ``predict`` on hand-normalised observations (Box and Dict), the trust rules for
normaliser pickles and one-line errors."""

from __future__ import annotations

import json
import pickle
import shutil
import subprocess
import sys
import textwrap
from importlib import resources

import numpy as np
import pytest

from smartcar_gym.agents.models import PRETRAINED_POLICIES, ActingOnly, load_model
from smartcar_gym.envs.policy_settings import policy_settings
from smartcar_gym.policy import (
    ObsNormalizer,
    Policy,
    PolicyError,
    as_policy,
)


def _provenance(name):
    place = resources.files("smartcar_gym") / "pretrained"
    if PRETRAINED_POLICIES[name]:
        place = place / PRETRAINED_POLICIES[name]
    return json.loads((place / "provenance.json").read_text()), place


@pytest.fixture(scope="module")
def shipped():
    return {name: Policy.load(name) for name in PRETRAINED_POLICIES}


def _hand_normalised(vec_normalize, obs, rms):
    """VecNormalize's formula, written out: (obs - mean) / sqrt(var + eps), clipped."""
    z = (obs - rms.mean) / np.sqrt(rms.var + vec_normalize.epsilon)
    return np.clip(z, -vec_normalize.clip_obs, vec_normalize.clip_obs).astype(np.float32)


@pytest.mark.parametrize("name", list(PRETRAINED_POLICIES))
def test_a_shipped_policy_has_the_settings_of_its_provenance(shipped, name):
    provenance, place = _provenance(name)
    policy = shipped[name]
    assert (policy.algo, policy.env_id, policy.env_kwargs) == (
        provenance["algo"], provenance["env"], provenance["env_kwargs"])
    with resources.as_file(place) as folder:
        assert policy.model_path == folder / "policy.zip"
        assert policy.normalizer_path == folder / "vecnormalize.pkl"
        assert policy.normalizer_source == (f"{folder / 'vecnormalize.pkl'} (that of the "
                                            f"shipped policy {folder})")
    assert policy.warning is None and isinstance(policy.normalizer, ObsNormalizer)
    assert type(policy.model).__name__ == provenance["algo"].upper()
    env = policy.make_env()
    try:
        assert env.spec.id == provenance["env"]
        assert env.observation_space.shape == policy.observation_space.shape
    finally:
        env.close()


@pytest.mark.parametrize("name", list(PRETRAINED_POLICIES))
def test_act_is_predict_on_the_hand_normalised_observation(shipped, name):
    policy = shipped[name]
    env = policy.make_env()
    try:
        obs, _ = env.reset(seed=7)
        obs, *_ = env.step(np.array([0.6, -0.3], dtype=np.float32))
    finally:
        env.close()
    vec_normalize = policy.normalizer.vec_normalize
    normed = _hand_normalised(vec_normalize, obs, vec_normalize.obs_rms)
    expected, _ = policy.model.predict(normed[None], deterministic=True)
    action = policy.act(obs)
    assert action.dtype == np.float32 and action.shape == (2,)
    np.testing.assert_allclose(action, expected[0], rtol=1e-6, atol=1e-7)
    raw, _ = policy.model.predict(obs[None].astype(np.float32), deterministic=True)
    assert np.abs(raw[0] - action).max() > 1e-3  # the normaliser matters


def test_deterministic_act_is_repeatable_and_sampling_is_seeded(shipped):
    policy = shipped["default"]
    obs = np.linspace(-1.0, 1.0, policy.observation_space.shape[0], dtype=np.float32)
    mean = policy.act(obs)
    assert all(policy.act(obs).tobytes() == mean.tobytes() for _ in range(3))
    samples = []
    for _ in range(2):
        policy.model.set_random_seed(3)
        samples.append([policy.act(obs, deterministic=False) for _ in range(2)])
    np.testing.assert_array_equal(samples[0], samples[1])
    assert not np.array_equal(samples[0][0], samples[0][1])
    assert not np.array_equal(samples[0][0], mean)


@pytest.mark.parametrize("name", ["default", "barn"])
def test_a_policy_loaded_to_act_acts_as_the_whole_model_and_cannot_train(shipped, name):
    policy = shipped[name]
    whole = load_model(policy.model_path, policy.algo)
    obs = np.random.default_rng(0).standard_normal(
        (64, *policy.observation_space.shape)).astype(np.float32)
    for deterministic in (True, False):
        actions = []
        for model in (policy.model, whole):
            model.set_random_seed(5)
            actions.append(model.predict(obs, deterministic=deterministic)[0])
        assert actions[0].tobytes() == actions[1].tobytes()
    assert isinstance(policy.model.policy.optimizer, ActingOnly)
    for call in (policy.model.policy.optimizer.step, policy.model.policy.optimizer.state_dict):
        with pytest.raises(RuntimeError,
                           match=r"loaded only to act .*models\.load_model\(path, algo\)"):
            call()
    assert type(whole.policy.optimizer).__name__ == "Adam"


def test_loading_a_policy_to_act_does_not_import_torchs_compiler():
    """A torch optimizer's first parameter group imports torch._dynamo (about a second)."""
    code = textwrap.dedent("""
        import sys
        import numpy as np
        from smartcar_gym.policy import Policy
        policy = Policy.load("barn")
        policy.act(np.zeros(policy.observation_space.shape, dtype=np.float32))
        print("torch._dynamo" in sys.modules)
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.stdout.strip() == "False", result.stderr


def test_settings_are_the_ros_policy_settings_of_the_env(shipped):
    assert shipped["robust"].settings == policy_settings("SmartCar-v0",
                                                         {"randomize": "default"})
    with pytest.raises(ValueError, match="SmartCarNav-v0 is not a goal-reaching SmartCarEnv"):
        shipped["nav"].settings  # noqa: B018


def test_overrides_replace_the_env_id_and_add_env_kwargs():
    policy = Policy.load("robust", env_id="SmartCarSim-v0", env_kwargs={"max_episode_steps": 5})
    assert policy.env_id == "SmartCarSim-v0"
    assert policy.env_kwargs == {"randomize": "default", "max_episode_steps": 5}


def test_a_planar_run_driven_on_another_engine_leaves_its_planar_params(tmp_path):
    """A run trained with planar_params (a planar fit) evaluated with --engine pybullet: the
    fit is the planar engine's, so it is left out (SmartCarEnv refuses it on pybullet)."""
    import yaml

    _, place = _provenance("default")
    with resources.as_file(place) as source:
        shutil.copyfile(source / "policy.zip", tmp_path / "model.zip")
        shutil.copyfile(source / "vecnormalize.pkl", tmp_path / "vecnormalize.pkl")
    (tmp_path / "config.yaml").write_text(yaml.safe_dump({
        "algo": "ppo", "env": "SmartCar-v0", "seed": 0, "n_envs": 16, "n_timesteps": 1,
        "hyperparams": {"normalize": True}, "eval_freq": 0, "eval_episodes": 1,
        "checkpoint_freq": 0,
        "env_kwargs": {"engine": "planar", "planar_params": "mujoco", "goal_range": [1, 2]}}))
    kept = Policy.load(tmp_path)
    assert kept.env_kwargs == {"engine": "planar", "planar_params": "mujoco",
                               "goal_range": [1, 2]}
    moved = Policy.load(tmp_path, env_kwargs={"engine": "pybullet"})
    assert moved.env_kwargs == {"engine": "pybullet", "goal_range": [1, 2]}
    env = moved.make_env()
    try:
        assert env.unwrapped.engine == "pybullet"
    finally:
        env.close()
    # named again with the engine, the fit is the user's choice: SmartCarEnv's error
    with pytest.raises(ValueError, match="planar_params is the planar engine's"):
        Policy.load(tmp_path, env_kwargs={"engine": "pybullet",
                                          "planar_params": "mujoco"}).make_env()


@pytest.fixture(scope="module")
def lonely(tmp_path_factory):
    """The shipped PPO model copied alone into a folder (no run, no provenance)."""
    folder = tmp_path_factory.mktemp("lonely")
    _, place = _provenance("default")
    with resources.as_file(place) as source:
        shutil.copyfile(source / "policy.zip", folder / "model.zip")
        shutil.copyfile(source / "vecnormalize.pkl", folder / "stats.pkl")
    return folder


class _Payload:
    """Unpickling it creates ``marker``: proof that a pickle was loaded."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_an_unnamed_pickle_near_a_model_is_not_loaded(lonely, tmp_path):
    folder = tmp_path / "download"
    folder.mkdir()
    shutil.copyfile(lonely / "model.zip", folder / "model.zip")
    marker = tmp_path / "code-ran"
    (folder / "vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    policy = Policy.load(folder / "model.zip", algo="ppo")
    assert not marker.exists()
    assert policy.normalizer is None and policy.normalizer_path is None
    assert policy.normalizer_source == "none (see the warning)"
    assert policy.warning.startswith(f"no normaliser loaded: {folder / 'model.zip'} is not in")
    assert (f"({folder / 'vecnormalize.pkl'} lies near the model but is not loaded unnamed: it "
            "is a pickle)") in policy.warning


def test_a_named_normaliser_gives_the_shipped_policys_actions(lonely, shipped):
    policy = Policy.load(lonely / "model.zip", algo="ppo", normalizer=lonely / "stats.pkl")
    assert policy.normalizer_source == f"{lonely / 'stats.pkl'} (named with --vecnormalize)"
    assert policy.warning is None and policy.env_id == "SmartCar-v0" and policy.env_kwargs == {}
    obs = np.linspace(-2.0, 2.0, policy.observation_space.shape[0], dtype=np.float32)
    assert policy.act(obs).tobytes() == shipped["default"].act(obs).tobytes()
    bare = as_policy(policy.model, lonely / "stats.pkl")
    assert bare.act(obs).tobytes() == policy.act(obs).tobytes()
    assert as_policy(policy) is policy
    with pytest.raises(ValueError, match="a Policy brings its own normaliser"):
        as_policy(policy, lonely / "stats.pkl")


def test_an_observation_of_another_shape_is_a_one_line_error(shipped):
    with pytest.raises(ValueError, match=r"^an observation of shape \(10,\); the policy expects "
                       r"\(21,\) \(the observation_space it was trained on\)$"):
        shipped["default"].act(np.zeros(10, dtype=np.float32))


def _error(source, **kwargs) -> str:
    with pytest.raises(PolicyError) as info:
        Policy.load(source, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_bad_sources_are_one_line_errors(lonely, tmp_path):
    missing = tmp_path / "missing.zip"
    assert _error(missing) == f"--model: no such file: {missing}"
    assert _error("defualt") == ("--model: no such file: defualt (nor the name of a shipped "
                                 f"policy: {', '.join(PRETRAINED_POLICIES)})")
    assert list(PRETRAINED_POLICIES)[:3] == ["default", "robust", "nav"]
    text = tmp_path / "text.zip"
    text.write_text("not a zip")
    assert _error(text, algo="ppo") == (f"--model: {text} is not a model (SB3 models are .zip "
                                        "files)")
    assert _error(tmp_path).startswith(f"--model: {tmp_path} is a folder but not a run folder")
    assert _error(lonely / "model.zip") == (
        f"cannot tell the algorithm of {lonely / 'model.zip'}: it is not in a run folder that "
        "says (smartcar-train's config.yaml, rl-baselines3-zoo's <env>/args.yml); pass --algo")
    assert _error(lonely / "model.zip", algo="sac") == (
        f"{lonely / 'model.zip'} holds a PPO model, not SAC: pass --algo ppo")
    assert _error(lonely / "model.zip", algo="a2c") == (
        "--algo: unknown algorithm 'a2c'; expected one of ppo, sac, td3")


def test_bad_normalisers_are_one_line_errors(lonely, tmp_path):
    missing = tmp_path / "none.pkl"
    assert _error(lonely / "model.zip", algo="ppo", normalizer=missing) == (
        f"--vecnormalize: no such file: {missing}")
    junk = tmp_path / "junk.pkl"
    junk.write_bytes(b"not a pickle")
    assert _error(lonely / "model.zip", algo="ppo", normalizer=junk).startswith(
        f"cannot load the normaliser {junk}: UnpicklingError: ")


def test_without_the_train_extra_the_error_names_it():
    code = textwrap.dedent("""
        import sys

        class Blocker:
            def find_spec(self, name, path=None, target=None):
                if name.partition(".")[0] in ("torch", "stable_baselines3"):
                    raise ModuleNotFoundError(name)
                return None

        sys.meta_path.insert(0, Blocker())
        from smartcar_gym.policy import Policy
        try:
            Policy.load("default")
        except ImportError as err:
            print(err)
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120)
    assert result.stdout.strip() == ("stable_baselines3, torch not installed; loading a policy "
                                     'needs the train extra: pip install "smartcar-gym[train]"')


FAST = {"max_episode_steps": 20, "controller_mode": "sim"}


@pytest.fixture(scope="module")
def goal_policy(tmp_path_factory):
    """An untrained SAC MultiInputPolicy on SmartCarGoal-v0 and VecNormalize statistics of
    40 random steps, saved as files and loaded back as a Policy."""
    from stable_baselines3 import SAC
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    folder = tmp_path_factory.mktemp("goal")
    venv = VecNormalize(DummyVecEnv([lambda: Policy(None, env_id="SmartCarGoal-v0",
                                                    env_kwargs=FAST).make_env()]))
    venv.seed(0)
    venv.action_space.seed(0)
    venv.reset()
    for _ in range(40):
        venv.step(np.array([venv.action_space.sample()]))
    SAC("MultiInputPolicy", venv, buffer_size=10, seed=0, policy_kwargs={"net_arch": [16]},
        device="cpu").save(folder / "model.zip")
    venv.save(folder / "stats.pkl")
    venv.close()
    return Policy.load(folder / "model.zip", algo="sac", env_id="SmartCarGoal-v0",
                       env_kwargs=FAST, normalizer=folder / "stats.pkl")


def test_dict_observations_of_the_goal_env(goal_policy):
    from smartcar_gym.agents.episodes import evaluate_policy_episodes

    env = goal_policy.make_env()
    try:
        obs, _ = env.reset(seed=2)
    finally:
        env.close()
    assert set(obs) == {"observation", "achieved_goal", "desired_goal"}
    vec_normalize = goal_policy.normalizer.vec_normalize
    normed = {key: _hand_normalised(vec_normalize, value, vec_normalize.obs_rms[key])[None]
              for key, value in obs.items()}
    expected, _ = goal_policy.model.predict(normed, deterministic=True)
    action = goal_policy.act(obs)
    np.testing.assert_allclose(action, expected[0], rtol=1e-6, atol=1e-7)
    assert action.tobytes() == goal_policy.act(obs).tobytes()
    [record] = evaluate_policy_episodes(goal_policy, "SmartCarGoal-v0", n_episodes=1, seed=2,
                                        env_kwargs=FAST)
    assert record.length == 20 or record.success
