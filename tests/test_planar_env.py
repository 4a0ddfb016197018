"""The envs on ``engine="planar"``: Gymnasium's checks, determinism, the batch per car bit for
bit, parameter files, errors, and the physics engines left as they were."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import smartcar_gym  # noqa: F401
from smartcar_gym.controller import compiled
from smartcar_gym.envs.vector import events
from smartcar_gym.sim.planar import dynamics
from smartcar_gym.sim.planar.layout import CX, CY, LOAD, MASS
from smartcar_gym.sim.planar.params import PlanarParams, PlanarParamsError, dump, load, resolve

PHYSICS_IDS = ("SmartCar-v0", "SmartCarGoal-v0", "SmartCarArrive-v0", "SmartCarNav-v0")
FIXTURES = os.path.join(os.path.dirname(__file__), "fixtures")
CASTERBOT = os.path.join(FIXTURES, "casterbot_description", "urdf", "casterbot.urdf.xacro")
CASTERBOT_YAML = os.path.join(FIXTURES, "casterbot_description", "config",
                              "casterbot_arbotix.yaml")


@pytest.mark.parametrize("env_id", PHYSICS_IDS)
def test_gymnasiums_checker_passes_on_planar(env_id: str) -> None:
    env = gym.make(env_id, engine="planar")
    try:
        check_env(env.unwrapped)  # with its render check: rgb_array, the only mode listed
        assert env.unwrapped.metadata["render_modes"] == ["rgb_array"]
    finally:
        env.close()


def rollout(env_id: str, seed: int, steps: int = 60, **kwargs) -> list[np.ndarray]:
    env = gym.make(env_id, engine="planar", **kwargs)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    out = [obs]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(
            rng.uniform(-1, 1, 2).astype(np.float32))
        out += [obs, np.array([reward]), info["pose"]]
        if terminated or truncated:
            out.append(env.reset()[0])
    env.close()
    return out


def test_seeded_rollouts_repeat_bit_for_bit() -> None:
    a, b = rollout("SmartCar-v0", 5), rollout("SmartCar-v0", 5)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    c = rollout("SmartCar-v0", 6)
    assert not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


@pytest.mark.skipif(not dynamics.COMPILED, reason="numba (the fast extra) is not installed")
def test_a_process_first_substeps_in_python_floats_are_the_compiled_ones(monkeypatch) -> None:
    """A process takes its first ``PYTHON_SUBSTEPS`` single-car substeps in Python floats,
    then numba's ``run_car``: a rollout crossing the switch, one wholly compiled and one
    wholly in Python are the same bit for bit."""
    calls = []
    run_car = dynamics.run_car
    monkeypatch.setattr(dynamics, "run_car", lambda *a: calls.append(a[-1]) or run_car(*a))
    runs = {}
    for left in (0, 300, 10**9):
        monkeypatch.setattr(dynamics, "_python_left", left)
        calls.clear()
        runs[left] = rollout("SmartCar-v0", 5)
        runs[left, "compiled"] = sum(calls)
    assert runs[10**9, "compiled"] == 0 < runs[300, "compiled"] < runs[0, "compiled"]
    for left in (300, 10**9):
        assert all(np.array_equal(x, y) for x, y in zip(runs[0], runs[left], strict=True))
    monkeypatch.setattr(dynamics, "_python_left", 3)  # the switch, once and for all
    assert [dynamics.compiled_run(2) for _ in range(4)] == [False, False, True, True]


@pytest.mark.skipif(not dynamics.COMPILED, reason="numba (the fast extra) is not installed")
def test_the_same_rollout_without_numba() -> None:
    """``SMARTCAR_GYM_NUMBA=0``: Python floats instead of the compiled loop, same numbers."""
    code = textwrap.dedent("""
        import sys, numpy as np
        sys.path.insert(0, %r)
        from test_planar_env import rollout
        np.save(sys.stdout.buffer, np.concatenate([np.ravel(x) for x in rollout(
            "SmartCar-v0", 5)]))
    """) % os.path.dirname(__file__)
    env = {**os.environ, "SMARTCAR_GYM_NUMBA": "0"}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, env=env,
                          check=True, timeout=300)
    import io
    python = np.load(io.BytesIO(done.stdout))
    compiled = np.concatenate([np.ravel(x) for x in rollout("SmartCar-v0", 5)])
    assert np.array_equal(python, compiled)


def test_the_car_drives_and_reaches_goals_as_commanded() -> None:
    """Forward at 0.3 m/s for 3 s from rest: 0.765 m on the planar engine, pybullet's 0.759 m
    within 2 %: the command reaches the wheels one period late and the car takes about 0.3 s
    to reach its speed (through the PID), about 0.3 * (3 - 0.1 - 0.35) m."""
    env = gym.make("SmartCar-v0", engine="planar", goal_range=(2.0, 2.4))
    env.reset(seed=0, options={"goal": (2.4, 0.0)})
    for _ in range(30):
        _, _, _, _, info = env.step(np.array([0.6, 0.0], dtype=np.float32))
    x, y, yaw = info["pose"]
    assert x == pytest.approx(0.7587, rel=0.02) and abs(y) < 1e-9 and abs(yaw) < 1e-9
    assert info["odom_error"] < 0.01
    env.close()


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("env_id", ["SmartCar-v0", "SmartCarGoal-v0"])
def test_the_batch_is_n_single_envs_bit_for_bit(env_id: str, mode: str) -> None:
    n, seed = 3, 11
    venv = gym.make_vec(env_id, num_envs=n, vectorization_mode="vector_entry_point",
                        engine="planar", autoreset_mode=mode, max_episode_steps=25)
    assert type(venv).__name__ == "SmartCarBatchVectorEnv" and venv.engine == "planar"
    envs = [gym.make(env_id, engine="planar", max_episode_steps=25) for _ in range(n)]
    obs, _ = venv.reset(seed=seed)
    first = [e.reset(seed=seed + i)[0] for i, e in enumerate(envs)]
    assert all(equal(car(obs, i), first[i]) for i in range(n))
    rng = np.random.default_rng(0)
    ended = [False] * n
    episodes = 0
    for _ in range(120):
        actions = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        obs, reward, terminated, truncated, info = venv.step(actions)
        for i, env in enumerate(envs):
            if ended[i]:
                expect, r, te, tr = env.reset()[0], 0.0, False, False
                ended[i] = False
            else:
                expect, r, te, tr, _ = env.step(actions[i])
            got = obs
            if mode == "SameStep" and (te or tr):
                got = info["final_obs"]
                expect_now = env.reset()[0]
                assert equal(car(obs, i), expect_now)
            assert equal(car(got, i), expect), f"car {i}"
            assert (reward[i], terminated[i], truncated[i]) == (r, te, tr)
            if te or tr:
                episodes += 1
                ended[i] = mode == "NextStep"
    assert episodes >= 2  # autoresets were exercised
    venv.close()
    for e in envs:
        e.close()


@pytest.mark.skipif(not dynamics.COMPILED, reason="numba (the fast extra) is not installed")
def test_the_batch_without_numba_is_the_same_batch(monkeypatch) -> None:
    """numba's loops (physics, motor drive, boards and controllers, reads, the event loop's
    substeps) and the numpy arrays: the same numbers for 64 cars reset at different steps (so
    each car's events fall apart)."""

    def run() -> list[np.ndarray]:
        venv = gym.make_vec("SmartCar-v0", num_envs=64, vectorization_mode="vector_entry_point",
                            engine="planar", max_episode_steps=25)
        out = [venv.reset(seed=5)[0]]
        rng = np.random.default_rng(1)
        for k in range(40):
            if k in (7, 18):  # a random third of the cars starts afresh: clocks fall apart
                out.append(venv.reset(options={"reset_mask": rng.random(64) < 0.3})[0])
            obs, reward, terminated, truncated, info = venv.step(
                rng.uniform(-1, 1, (64, 2)).astype(np.float32))
            out += [obs, reward, terminated | truncated, info["odom_pose"]]
        venv.close()
        return out

    fast = run()
    monkeypatch.setattr(dynamics, "COMPILED", False)
    monkeypatch.setattr(compiled, "COMPILED", False)
    monkeypatch.setattr(events, "COMPILED", False)
    slow = run()
    assert all(np.array_equal(a, b) for a, b in zip(fast, slow, strict=True))
    assert np.ptp(fast[-1][:, 0]) > 0.05  # the cars drove apart
    ends = [np.asarray(x) for x in fast if np.asarray(x).dtype == bool]
    assert 0 < np.count_nonzero(ends[-10:]) < 64 * 10  # some ended, at different steps


def car(obs, i):
    return {k: v[i] for k, v in obs.items()} if isinstance(obs, dict) else obs[i]


def equal(a, b) -> bool:
    if isinstance(a, dict):
        return all(np.array_equal(a[k], b[k]) for k in a)
    return np.array_equal(a, b)


def test_a_differential_drive_robot_is_batched_too() -> None:
    """The casterbot (two wheels and a sliding caster ball): its encoders start mid-tick in
    the batch as in the single env."""
    kwargs = dict(model=CASTERBOT, controller_config=CASTERBOT_YAML, engine="planar")
    venv = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point",
                        **kwargs)
    envs = [gym.make("SmartCar-v0", **kwargs) for _ in range(2)]
    obs, _ = venv.reset(seed=3)
    single = [e.reset(seed=3 + i)[0] for i, e in enumerate(envs)]
    assert all(np.array_equal(obs[i], single[i]) for i in range(2))
    actions = np.tile(np.array([[0.5, 0.0]], dtype=np.float32), (2, 1))
    for _ in range(30):
        obs, *_ = venv.step(actions)
        single = [e.step(actions[i])[0] for i, e in enumerate(envs)]
        assert all(np.array_equal(obs[i], single[i]) for i in range(2))
    # it drives straight: both wheels alike
    x, y, _ = envs[0].unwrapped.state.pose[0]  # the ground truth
    assert abs(y) < 0.01 and x > 0.5
    venv.close()
    for env in envs:
        env.close()


def test_the_lateral_friction_ratio_is_the_tyres_and_a_sliding_caster_stays_isotropic() -> None:
    """``lateral_friction_ratio`` corrects rolling tyres; the casterbot's ball (a sliding
    contact) resists sliding alike in every direction, as pybullet's friction does."""
    env = gym.make("SmartCar-v0", model=CASTERBOT, controller_config=CASTERBOT_YAML,
                   engine="planar")
    env.reset(seed=0)
    body = env.unwrapped.robot.body
    model = body.model_with(PlanarParams(friction_scale=1.0, lateral_friction_ratio=1.3))
    rows = list(zip(model.contact_groups, model.contacts, strict=True))
    [ball] = [c for g, c in rows if g < 0]
    assert ball[0] == pytest.approx(-0.08 - model.com[0]) and ball[5] == ball[6] == 0.5
    wheels = [c for g, c in rows if g >= 0]
    assert len(wheels) == 2 and all(w[6] == pytest.approx(1.3 * w[5]) for w in wheels)
    env.close()


def test_parameter_files_round_trip_and_name_what_is_wrong(tmp_path) -> None:
    params = PlanarParams(friction_scale=0.9, slip_speed=0.003, rolling_resistance=0.01,
                          load_shift_x=-0.004)
    path = tmp_path / "fit.yaml"
    path.write_text(dump(params, {"source": "test"}))
    assert load(path) == params
    assert resolve(str(path)) == params
    assert resolve({"slip_speed": 0.004}).slip_speed == 0.004
    assert resolve("mujoco").source.endswith("planar_mujoco.yaml")
    cases = {
        "planar: {slip_speed: 2.0}\n": "planar.slip_speed: expected a number in",
        "planar: {frction_scale: 1.0}\n": "planar.frction_scale: unknown key",
        "planar: {load_shift_x: 1.5}\n": r"planar.load_shift_x: expected a number in \[-1, 1\] m",
        "planar: [1, 2]\n": "planar: expected a mapping",
        "slip_speed: 0.01\n": "'planar:' section",
        "planar: {slip_speed: 0.01}\nextra: 1\n": "extra: unknown section",
        "planar: {slip_speed: [\n": "not valid YAML",
    }
    for text, message in cases.items():
        path.write_text(text)
        with pytest.raises(PlanarParamsError, match=message) as caught:
            load(path)
        assert str(path) in str(caught.value) and "\n" not in str(caught.value)
    with pytest.raises(PlanarParamsError, match="cannot read"):
        load(tmp_path / "missing.yaml")


def test_env_arguments_are_checked_in_one_line(tmp_path) -> None:
    with pytest.raises(ValueError, match="planar_params is the planar engine's"):
        gym.make("SmartCar-v0", planar_params="mujoco")
    with pytest.raises(ValueError, match="render_mode"):
        gym.make("SmartCar-v0", engine="planar", render_mode="human")
    bad = tmp_path / "bad.yaml"
    bad.write_text("planar: {lateral_friction_ratio: 0}\n")
    with pytest.raises(PlanarParamsError, match="lateral_friction_ratio"):
        gym.make("SmartCar-v0", engine="planar", planar_params=str(bad))


def test_the_load_shift_moves_the_static_loads_as_a_centre_of_mass_would(tmp_path) -> None:
    """``load_shift_x``: the contacts' loads balance about a point d ahead of the centre of
    mass (sum N x = W d, x from the centre of mass), and the weight is unchanged; a shift
    that leaves the contacts is refused naming the key and the file."""
    env = gym.make("SmartCar-v0", engine="planar")
    env.reset(seed=0)
    body = env.unwrapped.robot.body
    weight = body.model.car[MASS] * 9.81
    for shift in (0.0, 0.006, -0.01):
        contacts = np.array(body.model_with(PlanarParams(load_shift_x=shift)).contacts)
        x, load = contacts[:, CX], contacts[:, LOAD]
        assert load.sum() == pytest.approx(weight, rel=1e-9)
        assert (load * x).sum() == pytest.approx(weight * shift, abs=1e-9)
        assert (load * contacts[:, CY]).sum() == pytest.approx(0.0, abs=1e-9)
    front = np.array(body.model_with(PlanarParams(load_shift_x=0.006)).contacts)[:, LOAD]
    nominal = np.array(body.model_with(PlanarParams()).contacts)[:, LOAD]
    assert front[0] > nominal[0] and front[2] < nominal[2]  # front wheels first in the URDF
    env.close()
    far = tmp_path / "far.yaml"
    far.write_text("planar: {load_shift_x: 0.5}\n")
    tips = r"tip over \(planar.load_shift_x 0.5 m from .*far.yaml\)"
    with pytest.raises(ValueError, match=tips), \
            gym.make("SmartCar-v0", engine="planar", planar_params=str(far)) as tipping:
        tipping.reset(seed=0)  # closed either way: nothing left for the collector


def test_rgb_array_is_a_top_down_picture() -> None:
    env = gym.make("SmartCar-v0", engine="planar", render_mode="rgb_array",
                   render_width=160, render_height=120)
    env.reset(seed=0)
    image = env.render()
    assert image.shape == (120, 160, 3) and image.dtype == np.uint8
    colours = {tuple(c) for c in image.reshape(-1, 3)}
    assert (40, 80, 200) in colours  # the car's base
    assert len(colours) > 4
    env.close()


def test_the_default_engine_stays_pybullet() -> None:
    env = gym.make("SmartCar-v0")
    assert env.unwrapped.sim.engine == "pybullet" and env.unwrapped.engine == "pybullet"
    assert env.unwrapped.engine_options == {}  # no planar_params: the planar engine's own
    env.close()


def test_the_nav_batch_is_n_single_envs_bit_for_bit() -> None:
    """Lasers (noisy, at 13 Hz: scans between the controller's updates), clearance, the
    collision and proximity terms, autoresets with new obstacles."""
    n, seed = 3, 8
    kwargs = dict(engine="planar", laser={"noise_std_m": 0.01, "rate_hz": 13.0},
                  proximity_penalty=1.0, max_episode_steps=40)
    venv = gym.make_vec("SmartCarNav-v0", num_envs=n, vectorization_mode="vector_entry_point",
                        **kwargs)
    assert type(venv).__name__ == "SmartCarBatchVectorEnv"
    assert (venv.env_id, venv.engine) == ("SmartCarNav-v0", "planar")
    envs = [gym.make("SmartCarNav-v0", **kwargs) for _ in range(n)]
    obs, info = venv.reset(seed=seed)
    for i, env in enumerate(envs):
        single, single_info = env.reset(seed=seed + i)
        assert np.array_equal(obs[i], single)
        assert info["clearance"][i] == single_info["clearance"]
    rng = np.random.default_rng(1)
    ended, episodes = [False] * n, 0
    for _ in range(150):
        actions = rng.uniform(-1, 1, (n, 2)).astype(np.float32)
        obs, reward, terminated, truncated, info = venv.step(actions)
        for i, env in enumerate(envs):
            if ended[i]:
                expect, r, te, tr = env.reset()[0], 0.0, False, False
            else:
                expect, r, te, tr, single_info = env.step(actions[i])
                assert info["clearance"][i] == single_info["clearance"]
                assert info["collision"][i] == single_info["collision"]
            assert np.array_equal(obs[i], expect), f"car {i}"
            assert (reward[i], terminated[i], truncated[i]) == (r, te, tr)
            ended[i] = te or tr
            episodes += ended[i]
    assert episodes >= 3
    venv.close()
    for env in envs:
        env.close()


def test_the_laser_sees_what_pybullets_sees() -> None:
    """The same layout and pose: the planar scan's ranges equal pybullet's to its ray-cast
    tolerance (pybullet's hit points lie up to a millimetre off the surfaces)."""
    layout = [{"shape": "box", "position": [0.8, 0.1], "size": [0.3, 0.2], "yaw": 0.4},
              {"shape": "cylinder", "position": [-0.5, 0.7], "size": [0.25]}]
    scans = []
    for engine in ("pybullet", "planar"):
        env = gym.make("SmartCarNav-v0", engine=engine, obstacle_layout=layout)
        env.reset(seed=0)
        scans.append(env.unwrapped.laser.latest.ranges)
        env.close()
    finite = np.isfinite(scans[0])
    assert np.array_equal(finite, np.isfinite(scans[1]))
    assert finite.sum() > 20
    assert np.max(np.abs(scans[0][finite] - scans[1][finite])) < 2e-3


@pytest.mark.parametrize("values, message", [
    ({"slip_speed": 0.0}, r"PlanarParams: planar.slip_speed: expected a number in \[0.0001, 1\]"),
    ({"stiction_speed": 0.0}, r"PlanarParams: planar.stiction_speed: expected a number in"),
    ({"friction_scale": -1.0}, r"PlanarParams: planar.friction_scale: expected a number in"),
    ({"load_shift_x": float("nan")}, r"planar.load_shift_x: expected a number in"),
    ({"spin_reaction": True}, r"planar.spin_reaction: expected a number in"),
])
def test_a_params_object_is_checked_as_a_file_is_when_it_is_made(values, message) -> None:
    """A ``PlanarParams`` made in code meets the ranges a file's values do (a slip speed of 0
    divided by zero at reset, a negative friction scale drove without a word)."""
    with pytest.raises(PlanarParamsError, match=message) as caught:
        PlanarParams(**values)
    assert "\n" not in str(caught.value)
    made = PlanarParams(friction_scale=2, slip_speed=0.003)
    assert made.friction_scale == 2.0 and type(made.friction_scale) is float



def test_exponent_notation_in_a_file_is_read_as_the_number(tmp_path) -> None:
    """PyYAML reads ``5e-4`` (no dot) as text; a parameter file takes it as the number, and a
    value that is text but no number is named as text."""
    path = tmp_path / "small.yaml"
    path.write_text("planar:\n  slip_speed: 5e-4\n  stiction_speed: 1E-3\n"
                    "  load_shift_x: -4.5e-3\n")
    params = load(path)
    assert (params.slip_speed, params.stiction_speed, params.load_shift_x) == (5e-4, 1e-3,
                                                                                -4.5e-3)
    path.write_text("planar: {slip_speed: 5e-9}\n")
    with pytest.raises(PlanarParamsError, match=r"slip_speed: expected a number in "
                                                r"\[0.0001, 1\] m/s, got 5e-09"):
        load(path)
    path.write_text("planar: {slip_speed: fast}\n")
    with pytest.raises(PlanarParamsError, match=r"got 'fast' \(text\)"):
        load(path)


MESHBOT = os.path.join(FIXTURES, "meshbot_description", "urdf", "meshbot.urdf")


def test_a_planar_car_that_cannot_run_is_refused_when_the_env_is_made() -> None:
    """A load shift that tips the car, or a robot with too few ground contacts for the planar
    engine, is refused by ``gym.make`` (not at the first reset), in one line naming the cause:
    the load shift only where it is the cause, with the range the contacts allow."""
    with pytest.raises(ValueError) as caught:
        gym.make("SmartCar-v0", engine="planar", planar_params={"load_shift_x": 0.5})
    message = str(caught.value)
    assert "\n" not in message
    assert "tip over (planar.load_shift_x 0.5 m from planar_params)" in message
    low, high = (float(v) for v in message.split("contacts allow [")[1].split("]")[0]
                 .split(", "))
    assert -0.1 < low < 0.0 < high < 0.1
    for shift in (low * 0.99, high * 0.99):  # inside: made and reset
        env = gym.make("SmartCar-v0", engine="planar", planar_params={"load_shift_x": shift})
        env.reset(seed=0)
        env.close()
    with pytest.raises(ValueError) as caught:
        gym.make("SmartCar-v0", engine="planar", model=MESHBOT)
    message = str(caught.value)
    assert "2 ground contacts cannot carry a rigid body" in message
    assert "load_shift_x" not in message and "\n" not in message


@pytest.mark.parametrize("vectorization", ["subproc", "batched"])
def test_smartcar_eval_refuses_a_planar_car_that_cannot_run_with_exit_2(vectorization,
                                                                        capsys) -> None:
    from smartcar_gym.agents import cli_eval

    with pytest.raises(SystemExit) as exit_info:
        cli_eval.main(["--random", "--episodes", "2", "--no-progress", "--engine", "planar",
                       "--vectorization", vectorization, "--env-kwargs",
                       "planar_params={load_shift_x: 0.5}"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith("smartcar-eval: error: cannot make SmartCar-v0")
    assert "tip over (planar.load_shift_x 0.5 m from planar_params)" in last


AXLEBOT = os.path.join(FIXTURES, "axlebot_description", "urdf", "axlebot.urdf.xacro")
AXLEBOT_YAML = os.path.join(FIXTURES, "axlebot_description", "config", "axlebot_arbotix.yaml")


def test_a_robot_other_than_the_shipped_one_starts_from_neutral_values() -> None:
    """``planar_params=None`` is the shipped fit for the shipped smartcar only (however its
    model is given); another robot gets the neutral built-in values. The axlebot (centre of
    mass 1.4 mm behind its axle, a rear caster) would tip over with the smartcar's 4.5 mm
    load shift."""
    from smartcar_gym.model import SHIPPED_MODEL, load_model
    from smartcar_gym.sim.planar.params import shipped_path

    fit = load(shipped_path())
    for model in (None, str(SHIPPED_MODEL), load_model()):
        env = gym.make("SmartCar-v0", engine="planar", model=model)
        assert env.unwrapped.planar_params == fit and fit.load_shift_x != 0.0
        env.close()
    nav = gym.make("SmartCarNav-v0", engine="planar")  # the shipped xacro with laser:=true
    assert nav.unwrapped.planar_params == fit
    nav.close()
    env = gym.make("SmartCar-v0", engine="planar", model=AXLEBOT, controller_config=AXLEBOT_YAML)
    assert env.unwrapped.planar_params == PlanarParams()
    env.reset(seed=0)
    assert -0.0015 < env.unwrapped.robot.body.com[0] < -0.0013
    env.close()
    with pytest.raises(ValueError, match=r"tip over \(planar.load_shift_x 0.0045\d* m from "
                                         r".*planar_pybullet.yaml\)"):
        gym.make("SmartCar-v0", engine="planar", model=AXLEBOT, controller_config=AXLEBOT_YAML,
                 planar_params="pybullet")


def test_a_urdfs_parse_is_kept_and_each_body_gets_its_own_links():
    # every reset spawns the car again: the parse is kept (model.parsed), the mutable part not
    from smartcar_gym.model import load_model
    from smartcar_gym.model.errors import ModelError
    from smartcar_gym.sim.contracts import BASE
    from smartcar_gym.sim.planar.model import RobotTables

    text = load_model().urdf
    first, second = (RobotTables.from_text(text, "smartcar.urdf") for _ in range(2))
    assert first.robot is second.robot  # parsed once
    first.links[BASE].friction = 0.123  # what set_friction does (a variation)
    assert second.links[BASE].friction != 0.123
    assert second.links[BASE].mass == first.links[BASE].mass > 0
    frame = next(iter(first.frames.values()))
    with pytest.raises(ValueError, match="read-only"):
        frame[0, 3] = 1.0
    # a URDF that does not parse is refused each time, never kept
    for _ in range(2):
        with pytest.raises(ModelError, match="bad.urdf:1: XML syntax error"):
            RobotTables.from_text("<robot name='x'><link", "bad.urdf")
