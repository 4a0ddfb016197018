"""The env's own keywords, checked: render modes, substeps, the controller's 16-bit targets,
and how a call's keywords split between the env, its engine and its task."""

from __future__ import annotations

import inspect
import warnings
from collections.abc import Callable, Mapping
from typing import Any

from smartcar_gym import checks
from smartcar_gym.controller import ArbotixConfig, load_controller_config
from smartcar_gym.model import RobotModel, load_model
from smartcar_gym.sim.clock import check_max_substep
from smartcar_gym.sim.engines import (
    DEFAULT_ENGINE,
    Engine,
    default_max_substep,
    engine_kwargs,
    engine_owners,
    substep_range,
    window_unavailable,
)

MAX_RENDER_PX = 4096  # 8000 x 8000 took 2.4 GB and minutes per frame


class RenderModes(list):
    """The render modes, as ``metadata["render_modes"]`` lists them.

    ``gymnasium.make`` calls string methods on a ``render_mode`` it does not find in this list
    (``render_mode=1`` died with an AttributeError inside gymnasium); a value that is not a
    string is let through so that the env refuses it with a message naming it.
    """

    def __contains__(self, item: object) -> bool:
        return not isinstance(item, str) or super().__contains__(item)


def render_modes(engine: Engine, render_mode: Any) -> RenderModes:
    """The modes ``engine`` supports here: without a window (MuJoCo's viewer on macOS outside
    mjpython), only "rgb_array"; asking for "human" then says why."""
    why = window_unavailable(engine)
    if why is None:
        return RenderModes(["human", "rgb_array"])
    if render_mode == "human":
        raise ValueError(f"render_mode='human' is not available with engine={engine.name!r} here: "
                         f"{why}; use render_mode='rgb_array'")
    return RenderModes(["rgb_array"])


def max_substep(max_substep_s: float | None, physics_hz: float | None,
                engine: Engine | str = DEFAULT_ENGINE) -> float:
    """The longest physics substep (s): ``max_substep_s``, the deprecated ``physics_hz``'s
    period, or the engine's default."""
    if physics_hz is None:
        if max_substep_s is None:
            return default_max_substep(engine)
        return check_max_substep(max_substep_s, allowed=substep_range(engine))
    if max_substep_s is not None:
        raise ValueError(
            f"pass max_substep_s or physics_hz, not both (got max_substep_s={max_substep_s!r}, "
            f"physics_hz={physics_hz!r}); physics_hz is deprecated")
    hz = checks.positive_number("physics_hz", physics_hz)
    substep = check_max_substep(1.0 / hz, f"1 / physics_hz (physics_hz={physics_hz!r})")
    warnings.warn(f"physics_hz is deprecated: the simulator steps from event to event; pass "
                  f"max_substep_s={substep:g} instead", DeprecationWarning, stacklevel=4)
    return substep


def check_tick_targets(config: ArbotixConfig, max_linear: float, max_angular: float) -> None:
    """Refuse speeds whose wheel targets overflow the board's 16-bit ticks per frame."""
    wheel_speed = max_linear + max_angular * config.base_width_m / 2.0
    limit = config.max_target_speed_m_s
    if wheel_speed > limit:
        raise ValueError(
            f"max_linear={max_linear} and max_angular={max_angular} ask a wheel for "
            f"{wheel_speed:g} m/s, but with ticks_meter {config.ticks_meter:g} "
            f"({config.source}) the board's 16-bit target holds at most {limit:g} m/s")


def check_image(width: Any, height: Any) -> tuple[int, int]:
    """The rgb_array image's width and height (px), each at most ``MAX_RENDER_PX``."""
    size = f"rgb_array images are at most {MAX_RENDER_PX} px a side"
    return (checks.positive_int("render_width", width, MAX_RENDER_PX, size),
            checks.positive_int("render_height", height, MAX_RENDER_PX, size))


def load_config(config: Any, default: Any = None) -> ArbotixConfig:
    """The controller's configuration: ``config`` (an ``ArbotixConfig`` or a YAML file), or
    ``default`` (a task's) where it is None, or the shipped YAML."""
    config = checks.source("controller_config", default if config is None else config,
                           ArbotixConfig)
    return config if isinstance(config, ArbotixConfig) else load_controller_config(config)


def load_robot(model: Any, model_args: Mapping[str, Any] | None, package_path: Any,
               wheels: Any, task_args: Mapping[str, str]) -> RobotModel:
    """The robot: ``model`` (a ``RobotModel``, or a path loaded with ``model_args``) or the
    shipped xacro with the task's arguments (``task_args``) and ``model_args``."""
    if model_args is not None and not isinstance(model_args, Mapping):
        raise TypeError(f"model_args must be a dict of xacro arguments, got {model_args!r}")
    model = checks.source("model", model, RobotModel)
    if isinstance(model, RobotModel):
        return model
    mappings = dict(model_args or {})
    if model is None:
        mappings = {**task_args, **mappings}
    return load_model(model, mappings=mappings or None, package_path=package_path,
                      wheels=wheels)


def own_keywords(init: Callable[..., Any]) -> dict[str, Any]:
    """The keyword arguments of ``init`` (an ``__init__``) with their defaults."""
    return {name: p.default for name, p in inspect.signature(init).parameters.items()
            if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY) and name != "self"}


def split_keywords(label: str, kwargs: Mapping[str, Any], task_keywords: Mapping[str, Any],
                   env_keywords: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``kwargs`` (what the env did not name) as the engines' keywords and the task's; a
    keyword of neither is one line naming the closest of every keyword the env takes."""
    engines = engine_kwargs()
    clash = sorted(set(task_keywords) & engines)
    if clash:
        raise ValueError(f"{label}: the task's keyword {clash[0]!r} is also an engine's "
                         f"({', '.join(engine_owners(clash[0]))}); rename one of them")
    engine = {k: v for k, v in kwargs.items() if k in engines}
    task = {k: v for k, v in kwargs.items() if k not in engines}
    checks.check_keywords(label, task, sorted({*task_keywords, *env_keywords, *engines}))
    return engine, task
