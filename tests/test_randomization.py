"""The ``randomize`` argument: the nominal env kept bit for bit, seeded draws, checked ranges."""

from __future__ import annotations

import copy
import math
import os
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from git_trees import package_at

import smartcar_gym  # noqa: F401
from smartcar_gym.envs.randomization import (
    FACTOR_NAMES,
    FACTORS,
    Randomization,
    check_range,
)

REPO = Path(__file__).resolve().parent.parent
BEFORE = "de6473fed04f41342c43d98076dcdb767feb7eaa"  # the last commit without randomize
PRESET = REPO / "smartcar_gym" / "config" / "randomization.yaml"

DIGEST = textwrap.dedent("""
    import hashlib, sys
    import gymnasium as gym, numpy as np
    import smartcar_gym
    kwargs = eval(sys.argv[1])
    for env_id in ("SmartCar-v0", "SmartCarSim-v0"):
        env = gym.make(env_id, **kwargs)
        d = hashlib.sha256()
        obs, info = env.reset(seed=3)
        d.update(obs.tobytes() + info["pose"].tobytes() + env.unwrapped.goal.tobytes())
        for a in np.random.default_rng(7).uniform(-1, 1, (250, 2)).astype(np.float32):
            obs, r, te, tr, info = env.step(a)
            d.update(obs.tobytes() + np.float64(r).tobytes() + info["pose"].tobytes())
            d.update(info["odom_pose"].tobytes() + bytes([te, tr]))
            if te or tr:
                obs, info = env.reset()
                d.update(obs.tobytes() + env.unwrapped.goal.tobytes())
        env.close()
        print(env_id, d.hexdigest(), sorted(info))
""")


def _digests(pythonpath: Path, kwargs: str, cwd: Path) -> str:
    env = {**os.environ, "PYTHONPATH": str(pythonpath)}
    return subprocess.run([sys.executable, "-c", DIGEST, kwargs], capture_output=True,
                          text=True, env=env, cwd=cwd, timeout=300, check=True).stdout



# -- the nominal env ---------------------------------------------------------------------------
@pytest.mark.slow
def test_randomize_none_is_the_env_before_randomisation_bit_for_bit(tmp_path):
    """Observations, rewards, poses, odometry and info keys equal the code before the change."""
    tree = package_at(BEFORE, tmp_path, "before")
    if tree is None:
        pytest.skip(f"git cannot give the code before randomisation ({BEFORE}) here")
    before = _digests(tree, "{}", tmp_path)
    assert len(before.splitlines()) == 2
    assert _digests(REPO, "{'randomize': None}", tmp_path) == before
    assert _digests(REPO, "{}", tmp_path) == before


def _rollout(env_id: str, seed: int, steps: int = 80, **kwargs) -> tuple[list[bytes], list]:
    env = gym.make(env_id, **kwargs)
    out, infos = [], []
    try:
        obs, info = env.reset(seed=seed)
        out.append(obs.tobytes() + env.unwrapped.goal.tobytes())
        infos.append(info)
        for a in np.random.default_rng(1).uniform(-1, 1, (steps, 2)).astype(np.float32):
            obs, reward, te, tr, info = env.step(a)
            out.append(obs.tobytes() + np.float64(reward).tobytes() + info["pose"].tobytes())
            infos.append(info)
            if te or tr:
                obs, info = env.reset()
                out.append(obs.tobytes())
                infos.append(info)
    finally:
        env.close()
    return out, infos


@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarSim-v0"])
def test_an_empty_spec_is_the_nominal_robot_bit_for_bit(env_id):
    """Every factor at its nominal value is not applied at all: the same world, the same goals."""
    nominal, infos = _rollout(env_id, 5)
    empty, empty_infos = _rollout(env_id, 5, randomize={})
    assert empty == nominal
    assert "randomization" not in infos[0]
    drawn = empty_infos[0]["randomization"]
    assert {k: drawn[k] for k in FACTOR_NAMES} == {f.name: f.nominal for f in FACTORS}


# -- draws -------------------------------------------------------------------------------------
def test_same_seed_same_draw_and_rollout_other_seed_other_draw():
    a, infos_a = _rollout("SmartCar-v0", 11, randomize="default")
    b, infos_b = _rollout("SmartCar-v0", 11, randomize="default")
    c, infos_c = _rollout("SmartCar-v0", 12, randomize="default")
    assert a == b
    assert [i["randomization"] for i in infos_a] == [i["randomization"] for i in infos_b]
    assert infos_a[0]["randomization"] != infos_c[0]["randomization"]
    # every step's info carries the episode's draw
    assert all(i["randomization"] == infos_a[0]["randomization"] for i in infos_a[:20])


def test_each_episode_draws_anew_and_the_goals_are_the_nominal_envs():
    env = gym.make("SmartCar-v0", randomize="default")
    nominal = gym.make("SmartCar-v0")
    try:
        draws = []
        for seed in (0, None, None):
            _, info = env.reset(seed=seed)
            draws.append(info["randomization"])
        assert draws[0] != draws[1] != draws[2]
        for seed in (3, 4):  # seeded: the same goal as without randomisation
            env.reset(seed=seed)
            nominal.reset(seed=seed)
            assert np.array_equal(env.unwrapped.goal, nominal.unwrapped.goal)
    finally:
        env.close()
        nominal.close()


def test_draws_are_uniform_in_their_ranges_and_latency_is_whole():
    spec = Randomization.from_spec("default")
    rng = np.random.default_rng(0)
    draws = [spec.draw(rng).info for _ in range(400)]
    for factor in FACTORS:
        low, high = spec.ranges[factor.name]
        values = np.array([d[factor.name] for d in draws])
        assert low <= values.min() and values.max() <= high, factor.name
        if factor.integer:
            assert all(isinstance(v, int) for v in values.tolist())
            assert set(values.tolist()) == set(range(int(low), int(high) + 1))
        else:  # uniform: mean in the middle, spread over the range
            assert abs(values.mean() - (low + high) / 2) < 0.1 * (high - low), factor.name
            assert values.max() - values.min() > 0.9 * (high - low), factor.name
    assert len({d["noise_seed"] for d in draws}) == 400


def test_a_draw_takes_as_many_numbers_whatever_the_ranges():
    """So the robustness grid's plants see the same random stream for the same seed."""
    a, b = np.random.default_rng(9), np.random.default_rng(9)
    Randomization.from_spec("default").draw(a)
    Randomization.from_spec({"latency": 3}).draw(b)
    assert a.random() == b.random()


def test_fixed_values_are_drawn_exactly():
    spec = Randomization.from_spec({"track": 1.1, "latency": 2, "start_yaw": [0.25, 0.25]})
    draw = spec.draw(np.random.default_rng(0))
    assert draw.values["track"] == 1.1 and draw.values["latency"] == 2
    assert draw.start_pose == (0.0, 0.0, 0.25)
    assert draw.variation.track == 1.1 and draw.variation.latency == 2


def test_a_copy_keeps_the_spec_and_draws_the_same():
    env = gym.make("SmartCar-v0", randomize={"base_mass": [0.5, 2.0]}).unwrapped
    try:
        for twin in (copy.deepcopy(env), pickle.loads(pickle.dumps(env))):
            _, info = env.reset(seed=2)
            _, twin_info = twin.reset(seed=2)
            assert twin_info["randomization"] == info["randomization"]
            twin.close()
    finally:
        env.close()


def test_vector_envs_stack_the_draws():
    envs = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="sync",
                        randomize="default")
    try:
        _, info = envs.reset(seed=[1, 2])
        masses = info["randomization"]["base_mass"]
        assert masses.shape == (2,) and masses[0] != masses[1]
    finally:
        envs.close()


# -- the shipped preset ------------------------------------------------------------------------
def test_the_default_preset_randomises_every_factor_around_its_nominal_value():
    data = yaml.safe_load(PRESET.read_text())
    assert list(data) == list(FACTOR_NAMES)
    spec = Randomization.from_spec("default")
    for factor in FACTORS:
        low, high = spec.ranges[factor.name]
        assert low < high and low <= factor.nominal <= high, factor.name


def test_the_odometry_preset_halves_the_default_ranges_of_what_makes_odometry_drift():
    """``randomize="odometry"``: the true wheel radius and track, the encoders' scales and
    slip, each in half the default preset's range about its nominal value (0.98-1.02 gives
    0.99-1.01); every other factor stays nominal."""
    drift = {"wheel_radius", "track", "left_encoder_scale", "right_encoder_scale",
             "encoder_slip"}
    spec, default = Randomization.from_spec("odometry"), Randomization.from_spec("default")
    for factor in FACTORS:
        if factor.name in drift:
            low, high = default.ranges[factor.name]
            half = (factor.nominal + (low - factor.nominal) / 2,
                    factor.nominal + (high - factor.nominal) / 2)
            assert spec.ranges[factor.name] == pytest.approx(half, abs=1e-12), factor.name
            assert spec.ranges[factor.name][0] < spec.ranges[factor.name][1], factor.name
        else:
            assert spec.ranges[factor.name] == (factor.nominal, factor.nominal), factor.name
    env = gym.make("SmartCar-v0", engine="planar", randomize="odometry")
    try:
        _, info = env.reset(seed=1)
        drawn = info["randomization"]
        assert drawn["wheel_radius"] != 1.0 and drawn["base_mass"] == 1.0
    finally:
        env.close()


def test_a_yaml_file_and_a_path_object_are_read(tmp_path):
    path = tmp_path / "ranges.yaml"
    path.write_text("# mine\ntrack: [0.9, 1.1]\nlatency: 2\n")
    for spec in (str(path), path):
        ranges = Randomization.from_spec(spec).ranges
        assert ranges["track"] == (0.9, 1.1) and ranges["latency"] == (2, 2)
        assert ranges["base_mass"] == (1.0, 1.0)
    path.write_text("")
    assert Randomization.from_spec(path).ranges["track"] == (1.0, 1.0)


# -- errors ------------------------------------------------------------------------------------
def _bad_values(factor):
    lo, hi = factor.allowed
    span = hi - lo
    return [
        ([lo - 0.1 * span - 1, hi], "outside the accepted range"),
        ([lo, hi + 0.1 * span + 1], "outside the accepted range"),
        ([hi, lo], "low"),
        ([lo, lo, hi], "3 values"),
        ("wide", "got 'wide'"),
        ([lo, float("nan")], "got"),
        (None, "got None"),
        (True, "got True"),
    ]


@pytest.mark.parametrize("factor", FACTORS, ids=FACTOR_NAMES)
def test_every_range_is_checked_with_a_message_naming_the_factor(factor):
    for value, detail in _bad_values(factor):
        with pytest.raises(ValueError) as err:
            Randomization.from_spec({factor.name: value})
        message = str(err.value)
        assert message.startswith(f"randomize: {factor.name}: expected [low, high]"), message
        assert f"{factor.allowed[0]:g} <= low <= high <= {factor.allowed[1]:g}" in message
        assert detail in message, (value, message)
    # the ends of the accepted range are accepted
    assert check_range(factor, list(factor.allowed)) == factor.allowed


def test_latency_must_be_whole_periods():
    with pytest.raises(ValueError, match=r"latency: .*integers controller periods.*not whole"):
        Randomization.from_spec({"latency": [0, 1.5]})


def test_an_unknown_factor_is_named_with_a_close_match():
    with pytest.raises(ValueError, match=r"unknown factor 'wheel_fricton' \(did you mean "
                                         r"'wheel_friction'\?\); factors: ground_friction"):
        Randomization.from_spec({"wheel_fricton": [0.9, 1.1]})


@pytest.mark.parametrize("spec, error, match", [
    ("defualt", ValueError, r"randomize='defualt' is neither a preset "
                            r"\('default', 'odometry'\) nor a YAML file: no such file"),
    (7, TypeError, r"randomize must be None, a preset name .* got int: 7"),
    ([0.9, 1.1], TypeError, r"got list"),
])
def test_a_bad_spec_says_what_is_expected(spec, error, match):
    with pytest.raises(error, match=match):
        Randomization.from_spec(spec)


def test_bad_files_are_named(tmp_path):
    folder = tmp_path / "folder"
    folder.mkdir()
    with pytest.raises(ValueError, match="neither a preset .* not a file"):
        Randomization.from_spec(folder)
    broken = tmp_path / "broken.yaml"
    broken.write_text("track: [0.9, 1.1\n")
    with pytest.raises(ValueError, match=rf"randomize file {broken}: not valid YAML: .*line"):
        Randomization.from_spec(broken)
    listed = tmp_path / "list.yaml"
    listed.write_text("- track\n")
    with pytest.raises(ValueError, match=rf"{listed}: expected a mapping .* got list"):
        Randomization.from_spec(listed)
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text("track: [2, 1]\n")
    with pytest.raises(ValueError, match=rf"randomize file {wrong}: track: expected"):
        Randomization.from_spec(wrong)


def test_the_env_refuses_a_bad_spec_at_construction():
    with pytest.raises(ValueError, match="randomize: latency: expected"):
        gym.make("SmartCar-v0", randomize={"latency": [0, 11]})


def test_start_pose_is_where_the_robot_stands_and_odometry_starts_at_zero():
    env = gym.make("SmartCar-v0", randomize={"start_x": 0.05, "start_y": -0.04,
                                              "start_yaw": 0.3})
    try:
        _, info = env.reset(seed=0)
        x, y, yaw = info["pose"]
        assert math.isclose(x, 0.05, abs_tol=2e-3) and math.isclose(y, -0.04, abs_tol=2e-3)
        assert math.isclose(yaw, 0.3, abs_tol=2e-3)
        assert np.array_equal(info["odom_pose"], np.zeros(3))
    finally:
        env.close()
