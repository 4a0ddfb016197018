"""What the CLIs and gym.make say: smartcar-eval's header (the engine, how actions were chosen,
"1 episode"), an unknown env id for smartcar-train, and a misspelt env kwarg anywhere."""

from __future__ import annotations

import gymnasium as gym
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.agents import cli_eval
from smartcar_gym.registration import ENV_IDS

pytest.importorskip("stable_baselines3", reason="the CLIs need the train extra")

SHORT = ["--env-kwargs", "max_episode_steps=3", "--no-progress"]


def _run(main, argv: list[str], capsys) -> tuple[int, str, str]:
    try:
        code = main(argv)
    except SystemExit as exit_:
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


def _header(out: str) -> str:
    """The summary table's title (rich wraps it to the table's width)."""
    lines = out.strip().splitlines()
    return " ".join(line.strip() for line in lines[:next(
        i for i, line in enumerate(lines) if line.startswith("┏"))])


@pytest.mark.parametrize("engine", [None, "mujoco"])
def test_eval_header_names_the_engine(engine, capsys, monkeypatch):
    if engine == "mujoco":
        pytest.importorskip("smartcar_gym.sim.mujoco", reason="needs the mujoco extra")
    monkeypatch.setenv("COLUMNS", "200")  # the table's title on one line
    argv = ["--pretrained", "--episodes", "2", "--seed", "3", *SHORT]
    code, out, err = _run(cli_eval.main, argv + (["--engine", engine] if engine else []), capsys)
    assert code == 0, err
    assert _header(out) == (f"policy.zip on SmartCar-v0 ({engine or 'pybullet'}): 2 episodes, "
                            "seeds 3..4, deterministic")


def test_eval_random_says_random_actions_and_one_episode(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    argv = ["--random", "--episodes", "1", "--env", "SmartCarSim-v0", "--fail-under", "0",
            "--max-final-distance", "10", *SHORT]
    code, out, err = _run(cli_eval.main, argv, capsys)
    assert code == 0, err
    header = _header(out)
    assert header == "random-policy on SmartCarSim-v0 (pybullet): 1 episode, seed 0, random actions"
    assert "deterministic" not in out + err and "1 episodes" not in out + err
    assert "pass mark held: success rate 0.0% is not under --fail-under 0% (1 episode)" in err


def test_count_and_summary_title():
    assert cli_eval.count(1, "episode") == "1 episode"
    assert cli_eval.count(0, "episode") == "0 episodes"
    assert cli_eval.summary_title("m.zip", "SmartCarNav-v0", "mujoco", 100, 0, "stochastic") == (
        "m.zip on SmartCarNav-v0 (mujoco): 100 episodes, seeds 0..99, stochastic")


@pytest.mark.parametrize(("env_id", "closest"), [("SmartCar-v9", "SmartCar-v0"),
                                                  ("SmartCarNav", "SmartCarNav-v0"),
                                                  ("Smartcar-v0", "SmartCar-v0")])
def test_train_with_an_unknown_id_says_so_and_lists_the_ids(env_id, closest, capsys, tmp_path):
    from smartcar_gym.agents import cli_train

    argv = ["--env", env_id, "--run-dir", str(tmp_path / "run"), "--no-progress"]
    code, _, err = _run(cli_train.main, argv, capsys)
    assert code == 2
    [line] = [x for x in err.splitlines() if x.startswith("smartcar-train: error:")]
    assert line.startswith(f"smartcar-train: error: unknown env id {env_id!r}")
    assert f"did you mean {closest!r}?" in line
    assert line.endswith(f"registered smartcar ids: {', '.join(ENV_IDS)}")
    assert "hyperparameter" not in line and "yaml" not in line
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize(("env_id", "kwargs", "closest"), [
    ("SmartCar-v0", {"max_linar": 0.2}, "max_linear"),
    ("SmartCarSim-v0", {"goal_tolerence": 0.2}, "goal_tolerance"),
    ("SmartCarNav-v0", {"obstacle": 3}, "obstacles"),  # a Nav kwarg, passed through **kwargs
    ("SmartCarNav-v0", {"max_angualr": 1.0}, "max_angular"),  # a SmartCarEnv one, via Nav
    ("SmartCarGoal-v0", {"reward_typ": "dense"}, "reward_type"),
])
def test_a_misspelt_env_kwarg_names_the_closest_one(env_id, kwargs, closest):
    [key] = kwargs
    with pytest.raises(TypeError, match=rf"unexpected keyword argument '{key}' \(did you mean "
                                        rf"'{closest}'\?\)"):
        gym.make(env_id, **kwargs)


def test_an_unknown_env_kwarg_without_a_close_one_lists_the_kwargs():
    with pytest.raises(TypeError, match=r"unexpected keyword argument 'xyz'; it takes "
                                        r"arena_size, controller_config, .*, wheels( |$)"):
        gym.make("SmartCar-v0", xyz=1)


def test_a_misspelt_kwarg_in_make_vec_names_the_closest_one():
    with pytest.raises(TypeError, match=r"'max_linar' \(did you mean 'max_linear'\?\)"):
        gym.make_vec("SmartCarSim-v0", num_envs=2, vectorization_mode="vector_entry_point",
                     max_linar=0.2)


def test_the_env_signature_stays_inspectable():
    """inspect (and the ROS settings' defaults) see SmartCarEnv's own parameters; only the
    task's and the engines' keywords go through ``**kwargs`` (checked by name inside)."""
    import inspect

    from smartcar_gym.envs.settings import own_keywords
    from smartcar_gym.envs.smartcar_env import SmartCarEnv

    parameters = inspect.signature(SmartCarEnv).parameters
    assert parameters["max_linear"].default == 0.5 and parameters["task"].default == "reach"
    assert [p.name for p in parameters.values() if p.kind is p.VAR_KEYWORD] == ["kwargs"]
    assert not any(p.kind is p.VAR_POSITIONAL for p in parameters.values())
    own = own_keywords(SmartCarEnv.__init__)
    assert own["max_linear"] == 0.5 and "kwargs" not in own and "self" not in own


@pytest.mark.parametrize("cli", ["smartcar-eval", "smartcar-train"])
def test_the_clis_env_kwargs_name_the_closest_kwarg(cli, capsys, tmp_path):
    from smartcar_gym.agents import cli_train

    if cli == "smartcar-eval":
        main, argv = cli_eval.main, ["--random", "--episodes", "1", "--no-progress"]
    else:
        main, argv = cli_train.main, ["--timesteps", "64", "--run-dir", str(tmp_path / "run"),
                                  "--no-progress"]
    code, _, err = _run(main, [*argv, "--env-kwargs", "max_linar=0.2"], capsys)
    assert code == 2
    [line] = [x for x in err.splitlines() if x.startswith(f"{cli}: error:")]
    assert line == (f"{cli}: error: cannot make SmartCar-v0 with max_linar=0.2: SmartCar-v0 got "
                    "an unexpected keyword argument 'max_linar' (did you mean 'max_linear'?)")


def test_the_ros_policy_settings_name_the_closest_kwarg():
    from smartcar_gym.envs.policy_settings import policy_settings

    with pytest.raises(ValueError, match=r"^SmartCar-v0 got an unexpected keyword argument "
                                         r"'max_linar' \(did you mean 'max_linear'\?\)$"):
        policy_settings("SmartCar-v0", {"max_linar": 0.2})


def test_a_mark_line_never_reads_as_its_own_mark():
    """1929 of 2000 is 96.45 %: not "96.5% is under --fail-under 96.5%"; 0.1004 m is not
    "0.100 m is over 0.1 m"."""
    import argparse

    from smartcar_gym.agents.cli_eval import check_marks

    summary = {"success_rate": 1929 / 2000, "episodes": 2000, "mean_final_distance_m": 0.1004}
    args = argparse.Namespace(fail_under=96.5, max_final_distance=0.1)
    rate, distance = (mark["line"] for mark in check_marks(summary, args))
    assert rate == ("pass mark missed: success rate 96.45% is under --fail-under 96.5% "
                    "(2000 episodes)")
    assert distance == ("pass mark missed: mean final distance 0.1004 m is over "
                        "--max-final-distance 0.1 m (2000 episodes)")
    held = check_marks({**summary, "success_rate": 0.97, "mean_final_distance_m": 0.05}, args)
    assert [mark["line"].split(": ")[1] for mark in held] == [
        "success rate 97.0% is not under --fail-under 96.5% (2000 episodes)",
        "mean final distance 0.050 m is not over --max-final-distance 0.1 m (2000 episodes)"]


def test_a_fail_under_that_reads_as_a_fraction_gets_a_hint(capsys, tmp_path):
    out = tmp_path / "r.json"
    argv = ["--random", "--episodes", "2", "--env", "SmartCarSim-v0", "--fail-under", "0.95",
            "--vectorization", "batched", "--json", str(out), *SHORT]
    code, _, err = _run(cli_eval.main, argv, capsys)
    hint = "--fail-under 0.95 is 0.95 %, a percentage; for 95 % pass --fail-under 95"
    assert code == 1 and f"smartcar-eval: warning: {hint}" in err
    import json

    payload = json.loads(out.read_text())
    assert hint in payload["warnings"]
    assert payload["n_envs"] == 2  # the cars built (min of --n-envs' 128 and --episodes)


@pytest.mark.parametrize("value", ["-1", "0"])
def test_n_envs_says_positive_for_every_number_below_1(value, capsys):
    code, _, err = _run(cli_eval.main, ["--random", "--n-envs", value], capsys)
    assert code == 2 and f"expected a positive integer, got '{value}'" in err


def test_train_help_names_the_batched_engines(capsys):
    from smartcar_gym.agents import cli_train

    code, out, _ = _run(cli_train.main, ["--help"], capsys)
    text = " ".join(out.split())
    assert code == 0
    assert "SmartCarSim-v0: numpy arrays; --engine mujoco: MuJoCo in C; --engine planar: the " \
           "planar model in numpy arrays" in text


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("value", ["-1", "-7"])
def test_eval_seed_is_a_non_negative_integer(value, capsys, monkeypatch):
    monkeypatch.setattr(cli_eval, "_evaluate", lambda *a, **k: pytest.fail("evaluated"))
    code, _, err = _run(cli_eval.main, ["--random", "--episodes", "1", "--seed", value], capsys)
    assert code == 2 and "Traceback" not in err
    assert err.strip().splitlines()[-1] == (
        f"smartcar-eval: error: argument --seed: expected a non-negative integer, got "
        f"'{value}'")


@pytest.mark.parametrize(("module", "required"), [
    ("smartcar_gym.agents.cli_train", []), ("smartcar_gym.scale.rllib", ["--out", "x"]),
    ("smartcar_gym.calibration.cli", [])])
def test_every_seed_flag_is_a_non_negative_integer(module, required, capsys):
    import importlib

    parser = importlib.import_module(module).build_parser()
    with pytest.raises(SystemExit) as exit_:
        parser.parse_args([*required, "--seed", "-1"])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.strip().splitlines()[-1].endswith(
        "error: argument --seed: expected a non-negative integer, got '-1'")
    assert parser.parse_args([*required, "--seed", "3"]).seed == 3


def test_the_shipping_export_checks_its_counts(capsys):
    from smartcar_gym.agents import export

    for flag, value, expected in (("--seed", "-1", "a non-negative integer"),
                                  ("--episodes", "0", "a positive integer"),
                                  ("--n-envs", "-2", "a positive integer")):
        with pytest.raises(SystemExit) as exit_:
            export.main(["runs/x", flag, value])
        assert exit_.value.code == 2
        assert capsys.readouterr().err.strip().splitlines()[-1].endswith(
            f"error: argument {flag}: expected {expected}, got '{value}'")
