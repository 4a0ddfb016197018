"""Which physics engine runs a world: a registry of engine descriptions (``Engine``).

Each engine is one folder under ``sim/`` whose package exports ``ENGINE``, an ``Engine``: how
to make its simulator (and its car batch, if it has one), its substep default and range,
whether it can open a window, the env keywords only it takes, and the extra that installs
it. The package itself imports no physics library: the factories import the engine's modules
when called, so that listing the engines costs nothing and says which extra is missing.

The built-in engines are pybullet (the default, always installed), MuJoCo (the ``mujoco``
extra) and planar (numpy only). ``register_engine`` adds another, and so does an entry point
in the ``smartcar_gym.engines`` group of an installed package (its object: an ``Engine``);
docs/engines.md shows how to write one.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any

DEFAULT_ENGINE = "pybullet"
#: the entry-point group another package registers its engines in
ENTRY_POINT_GROUP = "smartcar_gym.engines"
#: the packages of the built-in engines, each exporting ``ENGINE``
BUILT_IN = ("smartcar_gym.sim.pybullet", "smartcar_gym.sim.mujoco", "smartcar_gym.sim.planar")
#: the keywords every engine's ``simulator`` is called with: none is an engine's own
SIMULATOR_KEYWORDS = ("max_substep_s", "gui", "draws")


@dataclass(frozen=True)
class Engine:
    """One physics engine, as the envs and tools see it.

    ``simulator(**options)`` makes a world (the ``Simulator`` protocol: ``max_substep_s``,
    ``gui`` and the engine's own ``kwargs`` as keywords); ``car_batch`` (or None) makes the
    batch of N cars the batched vector env steps (the ``CarBatch`` protocol). ``module`` is the
    library the engine needs and ``extra`` the pip line that installs it: without it, making
    a world is an ImportError that says what to install.
    """

    name: str
    simulator: Callable[..., Any]
    max_substep_s: float
    substep_range_s: tuple[float, float]
    #: why no window can open in this process (None: one can, given a display)
    window_unavailable: Callable[[], str | None] = lambda: None
    #: env keywords only this engine takes, each with its check/resolve function, called with
    #: the value given (None: not given) and the robot's ``RobotModel`` (None: not known)
    kwargs: dict[str, Callable[[Any, Any], Any]] = field(default_factory=dict)
    #: whether making an env spawns its robot once in a scratch world of this engine, so that
    #: a robot the engine cannot run is refused by ``gym.make`` (cheap engines only)
    spawn_check: bool = False
    #: whether its simulator takes ``draws=False`` (a world nothing will draw: no render mode),
    #: and then leaves out what is only drawn (pybullet's visual shapes)
    skips_drawing: bool = False
    car_batch: Callable[..., Any] | None = None
    #: whether ``car_batch`` runs differential-drive models (one drive wheel a side)
    batches_differential: bool = False
    module: str | None = None
    extra: str | None = None
    #: the pip requirements a world of it needs beyond smartcar-gym (what a dataset recorded
    #: on it lists)
    requirements: tuple[str, ...] = ()
    summary: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise ValueError(f"an engine's name must be an identifier, got {self.name!r}")
        if not callable(self.simulator):
            raise TypeError(f"engine {self.name!r}: simulator must be a callable that makes a "
                            f"world, got {self.simulator!r}")
        if self.car_batch is not None and not callable(self.car_batch):
            raise TypeError(f"engine {self.name!r}: car_batch must be None or a callable that "
                            f"makes a car batch, got {self.car_batch!r}")
        if not isinstance(self.kwargs, dict):
            raise TypeError(f"engine {self.name!r}: kwargs must be a dict of keyword -> check "
                            f"function, got {type(self.kwargs).__name__}")
        for key, check in self.kwargs.items():
            if not isinstance(key, str) or not key.isidentifier():
                raise ValueError(f"engine {self.name!r}: its keyword {key!r} is not an "
                                 "identifier")
            if key in SIMULATOR_KEYWORDS:
                raise ValueError(f"engine {self.name!r}: {key!r} is a keyword every engine's "
                                 f"simulator takes ({', '.join(SIMULATOR_KEYWORDS)}), not one "
                                 "of its own: rename it")
            if not callable(check):
                raise TypeError(f"engine {self.name!r}: kwargs[{key!r}] must be a function "
                                f"(value, robot model) -> value, got {check!r}")
        low, high = self.substep_range_s
        if not 0 < low <= self.max_substep_s <= high:
            raise ValueError(f"engine {self.name!r}: max_substep_s {self.max_substep_s} is not in "
                             f"its substep_range_s {self.substep_range_s}")

    def __reduce__(self) -> tuple[Any, tuple[str]]:
        """A copy (pickle, deepcopy) is the engine registered by this name."""
        return get_engine, (self.name,)

    def missing(self, exc: ModuleNotFoundError) -> ImportError:
        """The error for a world of this engine whose library is not installed."""
        how = f": {self.extra}" if self.extra else ""
        return ImportError(f"engine={self.name!r} needs the {exc.name} package, which is not "
                           f"installed{how}")


_REGISTRY: dict[str, Engine] = {}
_loaded = False
_BUILT_IN_NAMES: set[str] = set()
#: env keywords no engine may declare, each with whose it is (``reserve_keywords``)
_RESERVED: dict[str, str] = {}


def reserve_keywords(owner: str, names: Iterable[str]) -> None:
    """Keywords of ``owner`` (the env) that no engine may declare as its own: an engine
    registered later that does is refused (``register_engine``)."""
    for name in names:
        _RESERVED.setdefault(name, owner)


def clashes(engine: Engine) -> str | None:
    """What is wrong with ``engine``'s keywords among the env's (None: nothing)."""
    for key in engine.kwargs:
        if key in _RESERVED:
            return (f"engine {engine.name!r} declares the keyword {key!r}, which is "
                    f"{_RESERVED[key]}'s own: an engine's keywords must be names the env does "
                    "not take (rename it)")
    return None


def register_engine(engine: Engine, *, replace: bool = False) -> Engine:
    """Add ``engine`` to the registry (``replace``: over one of the same name, not over a
    built-in engine); one line if its name is taken or a keyword of it is the env's."""
    if not isinstance(engine, Engine):
        raise TypeError(f"register_engine takes an Engine, got {type(engine).__name__}")
    _load()
    if engine.name in _REGISTRY and not replace:
        raise ValueError(f"engine {engine.name!r} is registered already (replace=True to "
                         "replace it)")
    if engine.name in _BUILT_IN_NAMES:
        raise ValueError(f"engine {engine.name!r} is built in and cannot be replaced: "
                         "register yours under another name")
    clash = clashes(engine)
    if clash is not None:
        raise ValueError(clash)
    _REGISTRY[engine.name] = engine
    return engine


def _load() -> None:
    """The built-in engines, then those of the ``smartcar_gym.engines`` entry points."""
    global _loaded
    if _loaded:
        return
    _loaded = True
    for package in BUILT_IN:
        engine = importlib.import_module(package).ENGINE
        _REGISTRY.setdefault(engine.name, engine)
        _BUILT_IN_NAMES.add(engine.name)
    for point in entry_points(group=ENTRY_POINT_GROUP):
        engine = point.load()
        where = f"entry point {point.name!r} of {ENTRY_POINT_GROUP} ({point.value})"
        if not isinstance(engine, Engine):
            raise TypeError(f"{where} is a {type(engine).__name__}, not an Engine")
        clash = clashes(engine)
        if clash is not None:
            raise ValueError(f"{where}: {clash}")
        _REGISTRY.setdefault(engine.name, engine)


def engine_names() -> tuple[str, ...]:
    """Every registered engine's name, the built-in ones first."""
    _load()
    return tuple(_REGISTRY)


def get_engine(name: object, what: str = "engine") -> Engine:
    """The registered engine called ``name``; ValueError listing the engines otherwise."""
    _load()
    if not isinstance(name, str) or name not in _REGISTRY:
        raise ValueError(f"{what} must be one of {', '.join(map(repr, _REGISTRY))}, "
                         f"got {name!r}")
    return _REGISTRY[name]


def check_engine(value: object, name: str = "engine") -> str:
    """``value`` if it names an engine; ValueError listing the engines otherwise."""
    return get_engine(value, name).name


def engine_kwargs() -> set[str]:
    """Every env keyword that only one engine takes."""
    _load()
    return {key for engine in _REGISTRY.values() for key in engine.kwargs}


def engine_owners(key: str) -> list[str]:
    """The engines that take the env keyword ``key``."""
    _load()
    return [e.name for e in _REGISTRY.values() if key in e.kwargs]


def resolve(engine: str | Engine) -> Engine:
    """``engine`` as its description: an ``Engine`` itself, or the one registered by that
    name (ValueError listing the engines)."""
    return engine if isinstance(engine, Engine) else get_engine(engine)


def check_engine_keywords(engine: str | Engine, given: dict[str, Any]) -> None:
    """ValueError for a value in ``given`` (engine keywords: name -> value, None where not
    given) that ``engine`` does not take: another engine's, naming it, or no engine's."""
    spec = resolve(engine)
    for key, value in given.items():
        if value is not None and key not in spec.kwargs:
            owners = engine_owners(key)
            if not owners:
                raise ValueError(f"{key} is no engine's keyword; the engines' keywords are "
                                 f"{sorted(engine_kwargs())}")
            raise ValueError(f"{key} is the {owners[0]} engine's; pass engine={owners[0]!r} "
                             f"(engine is {spec.name!r})")


def engine_options(engine: str | Engine, given: dict[str, Any],
                   model: Any = None) -> dict[str, Any]:
    """The env keywords only some engine takes (``given``: name -> value, None where not
    given), for a world of ``engine`` and the robot ``model``: each of ``engine``'s own
    resolved by its ``kwargs`` function (None included: its default for that robot);
    ValueError for a value given for another engine's (``check_engine_keywords``)."""
    spec = resolve(engine)
    check_engine_keywords(spec, given)
    return {key: resolve(given.get(key), model) for key, resolve in spec.kwargs.items()}


def on_engine(env_kwargs: dict[str, Any], engine: str) -> dict[str, Any]:
    """``env_kwargs`` moved to ``engine``: ``engine`` set, and the kwargs only another engine
    takes left out (a planar run's ``planar_params``, when its policy is driven on pybullet)."""
    own = get_engine(engine).kwargs
    others = engine_kwargs() - set(own)
    return {**{k: v for k, v in env_kwargs.items() if k not in others}, "engine": engine}


def available(engine: str) -> bool:
    """Whether ``engine``'s library is installed (an engine without one always is)."""
    module = get_engine(engine).module
    if module is None:
        return True
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def batch_engines() -> list[str]:
    """The installed engines with a car batch (``Engine.car_batch``), in registration order."""
    return [n for n in engine_names() if get_engine(n).car_batch is not None and available(n)]


def batch_engine(preferred: str | None = None) -> str:
    """An installed engine with a car batch: ``preferred`` where it is one, else the first
    registered; ValueError if none is."""
    names = batch_engines()
    if not names:
        raise ValueError("no installed engine has a car batch (Engine.car_batch)")
    return preferred if preferred in names else names[0]


def default_max_substep(engine: str | Engine) -> float:
    """The longest physics substep (s) ``engine`` steps by default."""
    return resolve(engine).max_substep_s


def substep_range(engine: str | Engine) -> tuple[float, float]:
    """The substeps (s) ``engine`` accepts as ``max_substep_s``."""
    return resolve(engine).substep_range_s


def window_unavailable(engine: str | Engine) -> str | None:
    """Why a world of ``engine`` cannot open a window (``render_mode="human"``) in this
    process at all; None where it can, given a display."""
    return resolve(engine).window_unavailable()


def make_simulator(engine: str | Engine = DEFAULT_ENGINE, draws: bool = True,
                   **options: Any) -> Any:
    """A new simulator of ``engine`` with the simulator keywords (``max_substep_s``, ``gui``,
    ``gravity_m_s2``, ``ground_friction``, ...); keywords only another engine takes (a None
    ``planar_params`` on pybullet) are dropped. ``draws=False``: nothing will draw the world,
    and an engine that can (``Engine.skips_drawing``) leaves out what is only drawn.
    ``engine``: a registered name or its ``Engine``."""
    spec = resolve(engine)
    for key in engine_kwargs() - set(spec.kwargs):
        options.pop(key, None)
    if not draws and spec.skips_drawing:
        options["draws"] = False
    try:
        return spec.simulator(**options)
    except ModuleNotFoundError as exc:
        if spec.module is None or exc.name != spec.module:
            raise
        raise spec.missing(exc) from None


def add_engine_argument(parser: argparse.ArgumentParser | Any, default: str | None = None,
                        what: str = "the env's") -> None:
    """``--engine NAME`` on a command line (``args.engine``; None: not given), its choices
    the registered engines."""
    _load()
    notes = "; ".join(f"{e.name}: {e.summary}" for e in _REGISTRY.values() if e.summary)
    parser.add_argument("--engine", choices=engine_names(), default=default,
                        help=f"physics engine of {what} simulation (default: {DEFAULT_ENGINE}; "
                             f"{notes})")
