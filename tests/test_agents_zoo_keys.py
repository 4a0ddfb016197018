"""rl-baselines3-zoo's hyperparameter keys: read as the zoo reads them, or refused with a reason."""

import numpy as np
import pytest
import torch
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import StopTrainingOnMaxEpisodes
from stable_baselines3.her import HerReplayBuffer
from stable_baselines3.sac.policies import SACPolicy

from smartcar_gym.agents import zoo_keys
from smartcar_gym.agents.env_factory import check_env, make_env
from smartcar_gym.agents.hyperparams import (
    ALGOS,
    HyperparamsError,
    build_algo_kwargs,
    load_hyperparams,
    normalize_kwargs,
    policy_class,
    vecnormalize_settings,
)

RESCALE = "gymnasium.wrappers.RescaleAction"
CLIP = "gymnasium.wrappers.ClipReward"


@pytest.mark.parametrize("algo", ALGOS)
def test_shipped_files_log_is_success_in_the_zoo_form(algo):
    hp = load_hyperparams(algo, "SmartCar-v0")
    # what rl_zoo3 does with the string: eval, then Monitor(info_keywords=...) adds it to a tuple
    zoo_value = eval(hp["monitor_kwargs"], {})
    assert zoo_value == {"info_keywords": ("is_success",)}
    assert zoo_keys.monitor_kwargs(hp["monitor_kwargs"]) == zoo_value
    zoo_keys.check(hp)


def test_default_entry_serves_env_ids_the_file_does_not_name(tmp_path):
    path = tmp_path / "ppo.yaml"
    path.write_text("default:\n  n_timesteps: 1000\nSmartCar-v0:\n  n_timesteps: 2000\n")
    assert load_hyperparams("ppo", "SmartCarSim-v0", path) == {"n_timesteps": 1000}
    assert load_hyperparams("ppo", "SmartCar-v0", path) == {"n_timesteps": 2000}
    path.write_text("SmartCar-v0:\n  n_timesteps: 2000\n")
    with pytest.raises(HyperparamsError, match="no hyperparameters for env 'Other-v0' and no "
                                                "'default' entry; it has SmartCar-v0"):
        load_hyperparams("ppo", "Other-v0", path)


def test_run_keys_are_not_passed_to_the_algorithm():
    hp = {"env_wrapper": RESCALE, "vec_env_wrapper": None, "frame_stack": 2,
          "callback": [], "monitor_kwargs": {}, "env_kwargs": {"goal_range": [1, 2]},
          "n_envs": 2, "n_timesteps": 10, "policy": "MlpPolicy", "normalize": True}
    assert build_algo_kwargs("ppo", hp, 2) == {}


@pytest.mark.parametrize(("value", "specs"), [
    (None, []),
    (RESCALE, [(RESCALE, {})]),
    ([RESCALE, CLIP], [(RESCALE, {}), (CLIP, {})]),
    ([{RESCALE: {"min_action": -2.0, "max_action": 2.0}}, {CLIP: None}],
     [(RESCALE, {"min_action": -2.0, "max_action": 2.0}), (CLIP, {})]),
])
def test_class_specs_take_the_zoo_forms(value, specs):
    assert zoo_keys.class_specs(value, "env_wrapper") == specs


@pytest.mark.parametrize(("value", "message"), [
    ({RESCALE: {}, CLIP: {}}, "one-key mapping"),
    (3, "expected an import path"),
    ({RESCALE: [1, 2]}, "arguments of gymnasium.wrappers.RescaleAction must be a mapping"),
])
def test_class_specs_refuse_other_forms(value, message):
    with pytest.raises(HyperparamsError, match=f"env_wrapper: .*{message}"):
        zoo_keys.class_specs(value, "env_wrapper")


@pytest.mark.parametrize(("path", "message"), [
    ("Wrapper", "expected an import path such as module.Name, got 'Wrapper'"),
    ("no_such_module.Wrapper", "cannot import no_such_module"),
    ("gymnasium.wrappers.NoSuchWrapper", "module gymnasium.wrappers has no 'NoSuchWrapper'"),
])
def test_import_paths_that_fail_are_named(path, message):
    with pytest.raises(HyperparamsError, match=f"env_wrapper: {message}"):
        zoo_keys.import_object(path, "env_wrapper")


@pytest.mark.filterwarnings("ignore:.*precision lowered:UserWarning")  # RescaleAction's bounds
def test_env_wrappers_apply_in_order_outside_the_monitor():
    spec = [{RESCALE: {"min_action": -2.0, "max_action": 2.0}},
            {CLIP: {"min_reward": -0.01, "max_reward": 0.01}}]
    env = make_env("SmartCar-v0", monitor=True, env_wrapper=spec)
    try:
        assert type(env).__name__ == "ClipReward"
        assert type(env.env).__name__ == "RescaleAction"
        assert type(env.env.env).__name__ == "Monitor"
        assert env.action_space.high.tolist() == [2.0, 2.0]
        env.reset(seed=0)
        _, reward, *_ = env.step(np.array([2.0, 0.0], dtype=np.float32))
        assert -0.01 <= reward <= 0.01
    finally:
        env.close()


def test_a_wrapper_with_bad_arguments_fails_in_the_check_with_its_name():
    with pytest.raises(HyperparamsError, match=r"env_wrapper: gymnasium\.wrappers\.RescaleAction"
                                               r"\(bogus=1\) failed: TypeError"):
        check_env("SmartCar-v0", env_wrapper={RESCALE: {"bogus": 1}})


def test_monitor_kwargs_keep_is_success_and_take_strings():
    assert zoo_keys.monitor_kwargs(None) == {"info_keywords": ("is_success",)}
    assert zoo_keys.monitor_kwargs("dict(info_keywords=('distance', 'is_success'))") == {
        "info_keywords": ("is_success", "distance")}
    assert zoo_keys.monitor_kwargs({"info_keywords": ["odom_error"], "allow_early_resets": True}
                                   ) == {"info_keywords": ("is_success", "odom_error"),
                                         "allow_early_resets": True}


@pytest.mark.parametrize(("value", "message"), [
    ({"filename": "x"}, "filename cannot be set: Monitor files always go to <run-dir>/monitor"),
    ({"reset_keywords": ("goal",)}, "reset_keywords cannot be set: SB3 vector envs reset"),
    ({"info_keyword": ["x"]}, "unknown Monitor argument"),
    ({"info_keywords": "distance"}, "info_keywords must be a list of info keys"),
    ("dict(info_keywords=open('x'))", "cannot read"),
])
def test_monitor_kwargs_refused(value, message):
    with pytest.raises(HyperparamsError, match=message):
        zoo_keys.monitor_kwargs(value)


def test_info_keywords_must_be_in_the_env_info():
    check_env("SmartCar-v0", monitor_kwargs={"info_keywords": ("is_success", "distance")})
    with pytest.raises(HyperparamsError, match=r"info_keywords nope not in the info of "
                                               r"SmartCar-v0 \(it has distance, is_success"):
        check_env("SmartCar-v0", monitor_kwargs={"info_keywords": ("is_success", "nope")})


def test_frame_stack():
    assert zoo_keys.frame_stack(None) is None
    assert zoo_keys.frame_stack(4) == 4
    for bad in (0, True, "4", 2.5):
        with pytest.raises(HyperparamsError, match="frame_stack must be a whole number >= 1"):
            zoo_keys.frame_stack(bad)


def test_callbacks_are_made_with_their_arguments():
    (callback,) = zoo_keys.make_callbacks(
        {"stable_baselines3.common.callbacks.StopTrainingOnMaxEpisodes": {"max_episodes": 3}})
    assert isinstance(callback, StopTrainingOnMaxEpisodes) and callback.max_episodes == 3
    with pytest.raises(HyperparamsError, match="callback: collections.OrderedDict is not a "
                                               "Stable-Baselines3 callback"):
        zoo_keys.make_callbacks("collections.OrderedDict")
    with pytest.raises(HyperparamsError, match=r"StopTrainingOnMaxEpisodes\(no arguments\) "
                                               "failed: TypeError"):
        zoo_keys.make_callbacks("stable_baselines3.common.callbacks.StopTrainingOnMaxEpisodes")


def test_env_kwargs_must_be_a_mapping():
    assert zoo_keys.env_kwargs({"goal_range": [1, 2]}) == {"goal_range": [1, 2]}
    with pytest.raises(HyperparamsError, match="env_kwargs must be a mapping"):
        zoo_keys.env_kwargs("goal_range=[1, 2]")


def test_normalize_as_a_zoo_dict_string_and_its_discount():
    assert normalize_kwargs("dict(norm_obs=True, norm_reward=False)") == {
        "norm_obs": True, "norm_reward": False}
    with pytest.raises(HyperparamsError, match="normalize: unknown VecNormalize argument"):
        normalize_kwargs({"norm_ob": True})
    # as in the zoo: the algorithm's gamma if the entry sets one, else normalize's own
    assert vecnormalize_settings({"normalize": {"gamma": 0.9}, "gamma": 0.95}) == (
        {"norm_obs": True, "norm_reward": True}, 0.95)
    assert vecnormalize_settings({"normalize": "dict(gamma=0.9)"})[1] == 0.9
    assert vecnormalize_settings({"normalize": True}) == (
        {"norm_obs": True, "norm_reward": True}, 0.99)
    assert vecnormalize_settings({}) == (None, 0.99)


def test_normalize_kwargs_is_not_a_zoo_key():
    with pytest.raises(HyperparamsError, match="normalize_kwargs cannot be set: it is not a key "
                                               "of the zoo format"):
        build_algo_kwargs("ppo", {"normalize_kwargs": {"norm_reward": False}}, 2)


def test_replay_buffer_and_policy_classes_from_strings():
    kwargs = build_algo_kwargs("sac", {"replay_buffer_class": "HerReplayBuffer",
                                       "replay_buffer_kwargs": "dict(n_sampled_goal=4)"}, 2)
    assert kwargs["replay_buffer_class"] is HerReplayBuffer
    assert kwargs["replay_buffer_kwargs"] == {"n_sampled_goal": 4}
    path = "stable_baselines3.common.buffers.ReplayBuffer"
    assert build_algo_kwargs("td3", {"replay_buffer_class": path}, 2)[
        "replay_buffer_class"] is ReplayBuffer
    with pytest.raises(HyperparamsError, match="Stable-Baselines3 has no buffer 'Nope'"):
        build_algo_kwargs("sac", {"replay_buffer_class": "Nope"}, 2)
    assert policy_class({"policy": "stable_baselines3.sac.policies.SACPolicy"}) is SACPolicy
    assert policy_class({}) == "MlpPolicy"
    assert build_algo_kwargs("ppo", {"policy_kwargs": {"activation_fn": "nn.ReLU"}}, 2)[
        "policy_kwargs"]["activation_fn"] is torch.nn.ReLU


def test_monitor_logs_the_requested_info_keys(tmp_path):
    env = make_env("SmartCar-v0", {"max_episode_steps": 3}, monitor_file=str(tmp_path / "m"),
                   monitor_kwargs=zoo_keys.monitor_kwargs({"info_keywords": ["distance"]}))
    env.reset(seed=0)
    for _ in range(3):
        env.step(env.action_space.sample())
    env.close()
    lines = (tmp_path / "m.monitor.csv").read_text().splitlines()
    assert lines[1] == "r,l,t,is_success,distance"
    assert lines[2].split(",")[1] == "3"


@pytest.mark.parametrize(("override", "message"), [
    ("env_wrapper=no_such_module.Wrapper", "env_wrapper: cannot import no_such_module"),
    ("vec_env_wrapper=[Wrapper]", "vec_env_wrapper: expected an import path"),
    ("frame_stack=0", "frame_stack must be a whole number >= 1, got 0"),
    ("callback=collections.OrderedDict", "not a Stable-Baselines3 callback"),
    ("monitor_kwargs={info_keywords: [nope]}", "info_keywords nope not in the info"),
    ("env_kwargs=[1]", "env_kwargs must be a mapping"),
    ("policy=no_such_module.Policy", "policy: cannot import no_such_module"),
    ("normalize_kwargs={norm_reward: false}", "not a key of the zoo format"),
])
def test_smartcar_train_refuses_bad_zoo_keys_in_one_line(override, message, tmp_path, capsys):
    from smartcar_gym.agents import cli_train

    run = tmp_path / "runs" / "run"
    with pytest.raises(SystemExit) as exc:
        cli_train.main(["--n-envs", "1", "--timesteps", "64", "--eval-freq", "0", "--no-progress",
                    "--run-dir", str(run), "--hyperparams", override])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "Traceback" not in err
    last = err.splitlines()[-1]
    assert last.startswith("smartcar-train: error: ") and message in last, err
    assert list(tmp_path.iterdir()) == []
