"""Which physics engine runs a world: ``ENGINES`` and ``make_simulator``.

pybullet is the default and always installed; MuJoCo comes with the ``mujoco`` extra
(``pip install "smartcar-gym[mujoco]"``) and is imported only when a MuJoCo world is made;
``planar`` (``sim/planar/``: a rigid car in the plane on identified tyres, numpy only) is
always available.
"""

from __future__ import annotations

import argparse
from typing import Any

ENGINES: tuple[str, ...] = ("pybullet", "mujoco", "planar")
DEFAULT_ENGINE = "pybullet"
MUJOCO_EXTRA = 'pip install "smartcar-gym[mujoco]"'


# env kwargs that only one engine takes (SmartCarEnv refuses them on another)
ENGINE_KWARGS: dict[str, tuple[str, ...]] = {"planar": ("planar_params",)}


def on_engine(env_kwargs: dict[str, Any], engine: str) -> dict[str, Any]:
    """``env_kwargs`` moved to ``engine``: ``engine`` set, and the kwargs only another engine
    takes left out (a planar run's ``planar_params``, when its policy is driven on pybullet)."""
    check_engine(engine)
    others = {key for name, keys in ENGINE_KWARGS.items() if name != engine for key in keys}
    return {**{k: v for k, v in env_kwargs.items() if k not in others}, "engine": engine}


def check_engine(value: object, name: str = "engine") -> str:
    """``value`` if it names an engine; ValueError listing the engines otherwise."""
    if not isinstance(value, str) or value not in ENGINES:
        raise ValueError(f"{name} must be one of {', '.join(map(repr, ENGINES))}, got {value!r}")
    return value


def default_max_substep(engine: str) -> float:
    """The longest physics substep (s) an engine steps by default: 10 ms on pybullet and
    MuJoCo, ``planar.simulator.PLANAR_MAX_SUBSTEP_S`` on the planar engine."""
    if check_engine(engine) == "planar":
        from smartcar_gym.sim.planar.simulator import PLANAR_MAX_SUBSTEP_S

        return PLANAR_MAX_SUBSTEP_S
    from smartcar_gym.sim.clock import DEFAULT_MAX_SUBSTEP_S

    return DEFAULT_MAX_SUBSTEP_S


def substep_range(engine: str) -> tuple[float, float]:
    """The substeps (s) an engine accepts as ``max_substep_s``: ``clock.MAX_SUBSTEP_RANGE_S``
    (above 20 ms pybullet's contacts jitter), up to 50 ms on the planar engine (its implicit
    step is stable at any length)."""
    if check_engine(engine) == "planar":
        from smartcar_gym.sim.planar.simulator import PLANAR_SUBSTEP_RANGE_S

        return PLANAR_SUBSTEP_RANGE_S
    from smartcar_gym.sim.clock import MAX_SUBSTEP_RANGE_S

    return MAX_SUBSTEP_RANGE_S


def mujoco_simulator_class() -> type:
    """The MuJoCo ``Simulator`` class; ImportError naming the extra if mujoco is missing."""
    try:
        from smartcar_gym.sim.mujoco.simulator import MujocoSimulator
    except ModuleNotFoundError as exc:
        if exc.name != "mujoco":
            raise
        raise ImportError(
            f"engine='mujoco' needs the mujoco package, which is not installed: {MUJOCO_EXTRA}"
        ) from None
    return MujocoSimulator


def window_unavailable(engine: str) -> str | None:
    """Why a world of ``engine`` cannot open a window (``render_mode="human"``: pybullet's
    GUI, MuJoCo's viewer) in this process at all; None where it can, given a display."""
    if engine == "planar":
        return "the planar engine draws top-down pictures only (no window)"
    if engine != "mujoco":
        return None
    try:
        from smartcar_gym.sim.mujoco.window import unavailable
    except ModuleNotFoundError as exc:
        if exc.name != "mujoco":
            raise
        return None  # making the world says which extra is missing
    return unavailable()


def make_simulator(engine: str = DEFAULT_ENGINE, **options: Any) -> Any:
    """A new simulator of ``engine`` (see ``ENGINES``) with the ``Simulator`` keywords
    (``max_substep_s``, ``gui``, ``gravity_m_s2``, ``ground_friction``, ...)."""
    engine = check_engine(engine)
    if engine != "planar":
        options.pop("planar_params", None)
    if engine == "pybullet":
        from smartcar_gym.sim.simulator import Simulator

        return Simulator(**options)
    if engine == "planar":
        from smartcar_gym.sim.planar.simulator import PlanarSimulator

        return PlanarSimulator(**options)
    return mujoco_simulator_class()(**options)


def add_engine_argument(parser: argparse.ArgumentParser | Any, default: str | None = None,
                        what: str = "the env's") -> None:
    """``--engine {pybullet,mujoco,planar}`` on a command line (``args.engine``; None: not
    given)."""
    parser.add_argument("--engine", choices=ENGINES, default=default,
                        help=f"physics engine of {what} simulation (default: {DEFAULT_ENGINE}; "
                             f"mujoco needs the extra: {MUJOCO_EXTRA}; planar: docs/planar.md)")
