"""Engines as plug-ins: the registry (``sim.engines``), its entry points, the contracts
(``sim.contracts``) and ``examples/engine_plugin.py``."""

from __future__ import annotations

import argparse
import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest

from smartcar_gym.envs.settings import max_substep
from smartcar_gym.envs.smartcar_env import SmartCarEnv
from smartcar_gym.sim import contracts, engines
from smartcar_gym.sim.engines import (
    ENTRY_POINT_GROUP,
    Engine,
    add_engine_argument,
    engine_names,
    get_engine,
    make_simulator,
    register_engine,
)
from smartcar_gym.sim.planar.params import resolve

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def flatland():
    """The planar engine registered again as ``flatland``, for this test only."""
    engine = register_engine(dataclasses.replace(get_engine("planar"), name="flatland"))
    yield engine
    engines._REGISTRY.pop("flatland")


def test_the_example_registers_an_engine_and_runs_every_id_on_it():
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get(
        "PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, str(ROOT / "examples" / "engine_plugin.py")],
                          capture_output=True, text=True, timeout=600, env=env, cwd=ROOT)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "ok"


def test_the_built_in_engines_come_first():
    assert engine_names()[:3] == ("pybullet", "mujoco", "planar")
    # the lazy module-level names are gone: the registry answers
    assert not hasattr(engines, "ENGINES") and not hasattr(engines, "MUJOCO_EXTRA")
    assert get_engine("mujoco").extra == 'pip install "smartcar-gym[mujoco]"'


def test_register_engine_refuses_a_duplicate_and_what_is_no_engine(flatland):
    with pytest.raises(ValueError, match="engine 'flatland' is registered already"):
        register_engine(flatland)
    assert register_engine(flatland, replace=True) is flatland
    with pytest.raises(TypeError, match="register_engine takes an Engine, got dict"):
        register_engine({"name": "flatland"})


def test_an_engine_description_is_checked():
    planar = get_engine("planar")
    with pytest.raises(ValueError, match="an engine's name must be an identifier, got 'flat land'"):
        dataclasses.replace(planar, name="flat land")
    with pytest.raises(ValueError, match=r"max_substep_s 0.1 is not in its substep_range_s"):
        dataclasses.replace(planar, name="coarse", max_substep_s=0.1)


def test_an_engines_callables_and_keywords_are_checked_when_it_is_described():
    planar = get_engine("planar")
    with pytest.raises(TypeError, match="engine 'empty': simulator must be a callable that "
                                        "makes a world, got None"):
        dataclasses.replace(planar, name="empty", simulator=None)
    with pytest.raises(TypeError, match="engine 'odd': car_batch must be None or a callable"):
        dataclasses.replace(planar, name="odd", car_batch="cars")
    with pytest.raises(TypeError, match=r"engine 'odd': kwargs\['wind'\] must be a function"):
        dataclasses.replace(planar, name="odd", kwargs={"wind": 0.5})
    for shared in ("max_substep_s", "gui", "draws"):  # the simulator's own: never the engine's
        with pytest.raises(ValueError, match=f"engine 'odd': '{shared}' is a keyword every "
                                             "engine's simulator takes"):
            dataclasses.replace(planar, name="odd", kwargs={shared: lambda value, model: value})


def test_an_engine_may_not_declare_a_keyword_of_the_env():
    """A plug-in's keyword named like the env's own would never reach it (the env's signature
    takes it first): refused when the engine is registered, and a built-in engine is never
    replaced, so that no plug-in changes what pybullet, MuJoCo or planar run."""
    planar = get_engine("planar")
    for key in ("render_mode", "model", "engine", "max_linear"):
        with pytest.raises(ValueError, match=f"engine 'odd' declares the keyword '{key}', which "
                                             "is SmartCarEnv's own"):
            register_engine(dataclasses.replace(planar, name="odd",
                                                kwargs={key: lambda value, model: value}))
    assert "odd" not in engine_names()
    for name in ("pybullet", "planar"):
        with pytest.raises(ValueError, match=f"engine '{name}' is built in and cannot be "
                                             "replaced"):
            register_engine(dataclasses.replace(planar, name=name), replace=True)
    assert get_engine("planar") is planar and get_engine("pybullet").name == "pybullet"


def test_an_entry_point_declaring_a_keyword_of_the_env_is_named(monkeypatch):
    odd = dataclasses.replace(get_engine("planar"), name="odd",
                              kwargs={"render_mode": lambda value, model: value})
    _installed(monkeypatch, _Point("odd", odd))
    with pytest.raises(ValueError, match=r"entry point 'odd' of smartcar_gym.engines "
                                         r"\(other_package:odd\): engine 'odd' declares the "
                                         "keyword 'render_mode'"):
        engine_names()


@pytest.fixture
def windy():
    """A planar copy with a keyword of its own (``wind``), recording what its simulator is
    given, for this test only."""
    planar, given = get_engine("planar"), []

    def simulator(*, wind: float, **options):
        given.append(wind)
        return planar.simulator(**options)

    def check(value, model):
        return 0.0 if value is None else float(value)

    register_engine(dataclasses.replace(
        planar, name="windy", simulator=simulator, kwargs={**planar.kwargs, "wind": check}))
    yield given
    engines._REGISTRY.pop("windy")


def test_an_engines_own_keyword_reaches_it_and_only_it(windy):
    env = SmartCarEnv(engine="windy", wind=0.5)
    try:
        # every world it makes (the spawn check's scratch world too) gets it
        assert windy and set(windy) == {0.5} and env.engine_options["wind"] == 0.5
    finally:
        env.close()
    with pytest.raises(ValueError, match="wind is the windy engine's; pass engine='windy' "
                                         "\\(engine is 'pybullet'\\)"):
        SmartCarEnv(wind=0.5)


def test_a_task_keyword_an_engine_also_declares_is_refused():
    planar = get_engine("planar")
    register_engine(dataclasses.replace(
        planar, name="greedy", kwargs={**planar.kwargs, "goal_range": lambda value, model: value}))
    try:
        with pytest.raises(ValueError, match="the task's keyword 'goal_range' is also an "
                                             "engine's \\(greedy\\); rename one of them"):
            SmartCarEnv(engine="planar")
    finally:
        engines._REGISTRY.pop("greedy")


def test_get_engine_names_the_engines(flatland):
    assert get_engine("flatland") is flatland
    with pytest.raises(ValueError, match=r"engine must be one of 'pybullet', 'mujoco', "
                                         r"'planar', 'flatland', got 'bullet'"):
        get_engine("bullet")


class _Point:
    """An ``importlib.metadata.EntryPoint`` as ``entry_points(group=...)`` returns it."""

    def __init__(self, name: str, value: object) -> None:
        self.name, self.value, self._object = name, f"other_package:{name}", value

    def load(self) -> object:
        return self._object


def _installed(monkeypatch, *points: _Point) -> None:
    """A registry loaded afresh, with ``points`` as the installed entry points."""
    def entry_points(group: str):
        assert group == ENTRY_POINT_GROUP
        return list(points)

    monkeypatch.setattr(engines, "entry_points", entry_points)
    monkeypatch.setattr(engines, "_REGISTRY", {})
    monkeypatch.setattr(engines, "_loaded", False)


def test_an_entry_point_registers_an_engine(monkeypatch):
    other = dataclasses.replace(get_engine("planar"), name="other", summary="from a package")
    _installed(monkeypatch, _Point("other", other))
    assert engine_names() == ("pybullet", "mujoco", "planar", "other")
    assert get_engine("other") is other
    assert max_substep(None, None, "other") == get_engine("planar").max_substep_s
    assert max_substep(None, None, other) == get_engine("planar").max_substep_s


def test_an_entry_point_that_is_no_engine_is_named(monkeypatch):
    _installed(monkeypatch, _Point("broken", object()))
    with pytest.raises(TypeError, match=r"entry point 'broken' of smartcar_gym.engines "
                                        r"\(other_package:broken\) is a object, not an Engine"):
        engine_names()


def test_the_engine_option_offers_a_registered_engine(flatland):
    parser = argparse.ArgumentParser()
    add_engine_argument(parser)
    assert parser.parse_args(["--engine", "flatland"]).engine == "flatland"
    with pytest.raises(SystemExit):
        parser.parse_args(["--engine", "bullet"])


def test_a_missing_engine_library_names_its_extra(monkeypatch):
    def simulator(**options):
        import smartcar_gym_absent_physics  # noqa: F401

    engine = Engine("absent", simulator, 0.01, (1e-4, 0.02), module="smartcar_gym_absent_physics",
                    extra='pip install "smartcar-gym[absent]"')
    monkeypatch.setitem(engines._REGISTRY, "absent", engine)
    with pytest.raises(ImportError, match=r"engine='absent' needs the smartcar_gym_absent_physics "
                                          r"package, which is not installed: pip install "
                                          r"\"smartcar-gym\[absent\]\""):
        make_simulator("absent", max_substep_s=0.01)


def test_an_engine_keyword_follows_the_engine_that_takes_it(flatland):
    env = SmartCarEnv(engine="flatland", planar_params="mujoco")
    assert env.planar_params == resolve("mujoco")
    assert env.sim.params == resolve("mujoco")
    env.close()
    default = SmartCarEnv()  # pybullet: no engine keyword of its own
    try:
        assert default.engine_options == {} and default.planar_params is None
    finally:
        default.close()
    with pytest.raises(ValueError, match=r"planar_params is the planar engine's; pass "
                                         r"engine='planar' \(engine is 'pybullet'\)"):
        SmartCarEnv(planar_params="mujoco")


def test_only_an_engine_with_a_window_or_a_solver_offers_them():
    planar = make_simulator("planar")
    bullet = make_simulator("pybullet")
    try:
        assert not isinstance(planar, contracts.Window | contracts.ConvergesContacts)
        assert isinstance(bullet, contracts.Window)
        assert isinstance(bullet, contracts.ConvergesContacts)
        assert contracts.window_of(bullet) is None  # headless: no window open
        assert contracts.window_of(planar) is None
    finally:
        planar.close()
        bullet.close()


def test_a_batch_of_rays_is_pybullets_most_on_every_engine():
    from smartcar_gym.sim.pybullet.bullet import pybullet
    from smartcar_gym.sim.rays import MAX_RAYS

    assert MAX_RAYS == pybullet.MAX_RAY_INTERSECTION_BATCH_SIZE


def test_pybullets_names_live_in_its_folder_and_the_facade_has_no_aliases():
    import smartcar_gym.sim as sim
    from smartcar_gym.sim.clock import NS_PER_S
    from smartcar_gym.sim.pybullet.body import Body as PybulletBody
    from smartcar_gym.sim.pybullet.simulator import Simulator as PybulletSimulator

    assert not hasattr(sim, "Simulator") and not hasattr(sim, "Body")
    world = make_simulator("pybullet")
    try:
        assert type(world) is PybulletSimulator and world.engine == "pybullet"
    finally:
        world.close()
    assert PybulletBody.__module__ == "smartcar_gym.sim.pybullet.body"
    assert all(hasattr(contracts, name) for name in ("BASE", "LinkDynamics", "BoxPart"))
    assert NS_PER_S == 1_000_000_000
