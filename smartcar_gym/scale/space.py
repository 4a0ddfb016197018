"""The search space of a ``smartcar-tune`` sweep, read from YAML and the command line.

A space file (see the shipped ``smartcar_gym/config/tune_ppo.yaml``)::

    algo: ppo
    env: SmartCar-v0
    timesteps: 40960            # per trial (default: the hyperparameter file's n_timesteps)
    hyperparams:                # on top of the shipped <algo>.yaml (or hyperparams_file)
      n_envs: 1
      learning_rate: {loguniform: [1.0e-4, 1.0e-3]}
      n_epochs: {grid: [10, 20]}
    seed: {grid: [0, 1, 2]}
    early_stopping: {grace_period: 10240, reduction_factor: 2}   # ASHA; absent or null: none

``vectorization: batched`` makes every trial a ``smartcar-train --vectorization batched`` run
on the hyperparameters' ``<env>-batched-<engine>`` (else ``<env>-batched``) entry, as that
command takes it (the shipped ``tune_ppo_batched.yaml``).

Any value under ``hyperparams`` and ``env_kwargs``, and ``seed``, is either fixed or a search
dimension: a mapping with one key out of ``DIMENSIONS``. Everything is checked here, before
Ray starts, and errors name the file and the key. ``Sweep.trial_values`` lists the trials:
Ray Tune runs them as a grid, so nothing here needs Ray.
"""

from __future__ import annotations

import copy
import itertools
import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from smartcar_gym.agents.hyperparams import (
    ALGOS,
    HyperparamsError,
    build_algo_kwargs,
    discount,
    hyperparams_variant,
    load_hyperparams,
    normalize_kwargs,
    parse_value,
    run_int,
)
from smartcar_gym.agents.vec_envs import VECTORIZATIONS

# name -> what it takes
DIMENSIONS = {
    "grid": "a non-empty list (every value is tried)",
    "choice": "a non-empty list (one value drawn per sample)",
    "uniform": "[low, high], numbers with low < high",
    "loguniform": "[low, high], numbers with 0 < low < high",
    "randint": "[low, high], whole numbers with low < high (high excluded)",
}
KEYS = ("algo", "env", "vectorization", "hyperparams_file", "hyperparams", "env_kwargs", "seed",
        "num_samples", "timesteps", "cpus_per_trial", "eval_freq", "eval_episodes",
        "eval_start", "early_stopping", "random_seed")
ASHA_KEYS = ("grace_period", "reduction_factor")
# A grace period that does not fit a shortened trial is scaled to an evaluation in this first
# part of it, so ASHA still compares trials at least once before their end (the shipped space's
# 30,720 steps do not fit trials of up to 30,720 steps; half of 20,480 is its first evaluation).
GRACE_FRACTION = 0.5


class SpaceError(ValueError):
    """A search space is invalid (the message names the file, the key and what was expected)."""


@dataclass(frozen=True)
class Dimension:
    """One search dimension: ``kind`` (a key of ``DIMENSIONS``) and its values or bounds."""

    kind: str
    values: tuple[Any, ...]

    def samples(self) -> list[Any]:
        """Values to check the dimension with: every listed value, or both bounds."""
        if self.kind == "randint":
            return [self.values[0], self.values[1] - 1]
        return list(self.values)

    def draw(self, rng: np.random.Generator) -> Any:
        """One random value (``grid`` has none: it is expanded, not drawn)."""
        if self.kind == "choice":
            return self.values[int(rng.integers(len(self.values)))]
        low, high = self.values
        if self.kind == "uniform":
            return float(rng.uniform(low, high))
        if self.kind == "loguniform":
            return float(math.exp(rng.uniform(math.log(low), math.log(high))))
        if self.kind == "randint":
            return int(rng.integers(low, high))
        raise ValueError(f"a {self.kind} dimension is expanded, not drawn")

    def to_yaml(self) -> dict[str, list[Any]]:
        return {self.kind: list(self.values)}


@dataclass
class Sweep:
    """A checked search space plus the settings every trial shares."""

    algo: str
    env: str
    hyperparams: dict[str, Any]  # the base file's, with the space's values and dimensions
    env_kwargs: dict[str, Any]
    seed: int | Dimension
    timesteps: int
    num_samples: int = 1
    cpus_per_trial: int = 1
    vectorization: str = "subproc"  # how each trial runs its envs (smartcar-train's option)
    eval_freq: int = 10_240
    eval_episodes: int = 20
    eval_start: int = 0
    early_stopping: dict[str, Any] | None = None  # ASHA's settings; None: no early stopping
    random_seed: int = 0
    source: str = ""
    notes: list[str] = field(default_factory=list)  # what build_sweep changed, one line each

    def dimensions(self) -> dict[str, Dimension]:
        """The searched values by name: ``seed``, hyperparameter names, ``env_kwargs.<key>``."""
        found = {f"env_kwargs.{k}": v for k, v in self.env_kwargs.items()
                 if isinstance(v, Dimension)}
        found.update({k: v for k, v in self.hyperparams.items() if isinstance(v, Dimension)})
        if isinstance(self.seed, Dimension):
            found["seed"] = self.seed
        return found

    def to_yaml(self) -> dict[str, Any]:
        """The sweep as a space file (what ``smartcar-tune`` writes to ``<out>/sweep.yaml``)."""
        def plain(value: Any) -> Any:
            return value.to_yaml() if isinstance(value, Dimension) else value

        data = {key: getattr(self, key) for key in KEYS if hasattr(self, key)}
        data["hyperparams"] = {k: plain(v) for k, v in self.hyperparams.items()}
        data["env_kwargs"] = {k: plain(v) for k, v in self.env_kwargs.items()}
        data["seed"] = plain(self.seed)
        return data

    def trial_values(self) -> list[dict[str, Any]]:
        """The searched values of every trial, in order (``seed`` last): for each of
        ``num_samples`` samples, each combination of the grid dimensions, with fresh draws of
        the random ones (seeded by ``random_seed``), is run with each seed. So the seeds of a
        configuration train the same values, and a rerun of the sweep makes the same trials."""
        rng = np.random.default_rng(self.random_seed)
        dims = {k: v for k, v in self.dimensions().items() if k != "seed"}
        grid = [k for k, v in dims.items() if v.kind == "grid"]
        trials = []
        for _ in range(self.num_samples):
            for combination in itertools.product(*(dims[k].values for k in grid)):
                values = dict(zip(grid, combination, strict=True))
                values.update({k: v.draw(rng) for k, v in dims.items() if v.kind != "grid"})
                values = {k: values[k] for k in dims}  # in the space's order
                seed = self.seed
                seeds = (seed.values if isinstance(seed, Dimension) and seed.kind == "grid"
                         else [seed.draw(rng) if isinstance(seed, Dimension) else seed])
                trials += [{**values, "seed": int(s)} for s in seeds]
        return trials

    def trial_config(self, values: dict[str, Any]) -> dict[str, Any]:
        """A trial's complete config from its searched values (see ``trial_values``)."""
        hyperparams = copy.deepcopy(self.hyperparams)
        env_kwargs = copy.deepcopy(self.env_kwargs)
        seed = values.get("seed", self.seed)
        for name, value in values.items():
            if name.startswith("env_kwargs."):
                env_kwargs[name.removeprefix("env_kwargs.")] = value
            elif name != "seed":
                hyperparams[name] = value
        return {
            "algo": self.algo, "env": self.env, "vectorization": self.vectorization, "seed": seed,
            "timesteps": self.timesteps, "eval_freq": self.eval_freq,
            "eval_episodes": self.eval_episodes, "eval_start": self.eval_start,
            "hyperparams": hyperparams, "env_kwargs": env_kwargs,
        }


def shipped_space_file(algo: str = "ppo", vectorization: str = "subproc") -> Path:
    """The example search space shipped in ``smartcar_gym/config/tune_<algo>.yaml`` (batched
    trials: ``tune_<algo>_batched.yaml``)."""
    suffix = "" if vectorization == "subproc" else f"_{vectorization}"
    return Path(str(resources.files("smartcar_gym") / "config" / f"tune_{algo}{suffix}.yaml"))


def parse_dimension(value: Any, where: str) -> Any:
    """``value`` as a ``Dimension`` if it is a one-key mapping naming one, else unchanged."""
    if not (isinstance(value, dict) and len(value) == 1 and next(iter(value)) in DIMENSIONS):
        return value
    kind, values = next(iter(value.items()))
    if isinstance(values, list):  # YAML 1.1 reads 1e-4 (no dot) as a string: a number is meant
        values = [parse_value(v) if isinstance(v, str) else v for v in values]
    expected = f"{where}: {{{kind}: ...}} takes {DIMENSIONS[kind]}, got {values!r}"
    if not isinstance(values, list) or not values:
        raise SpaceError(expected)
    if kind in ("grid", "choice"):
        return Dimension(kind, tuple(values))
    if len(values) != 2 or not all(_is_number(v) for v in values) or values[0] >= values[1]:
        raise SpaceError(expected)
    if kind == "loguniform" and values[0] <= 0:
        raise SpaceError(expected)
    if kind == "randint" and not all(isinstance(v, int) for v in values):
        raise SpaceError(expected)
    return Dimension(kind, (values[0], values[1]))


def load_space(path: str | Path | None = None) -> tuple[dict[str, Any], Path]:
    """The raw mapping of a space file (default: the shipped PPO space) and its path."""
    path = Path(path) if path is not None else shipped_space_file()
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as err:
        raise SpaceError(f"cannot read the search space {path}: {err.strerror}") from err
    except yaml.YAMLError as err:
        raise SpaceError(f"{path}: not valid YAML: {err}") from err
    if not isinstance(data, dict):
        raise SpaceError(f"{path}: expected a mapping (algo, hyperparams, seed, ...), "
                         f"got {type(data).__name__}")
    return data, path


def build_sweep(data: dict[str, Any], source: str | Path,
                base_dir: Path | None = None, *, fit_early_stopping: bool = False) -> Sweep:
    """Check a space mapping and merge it onto its base hyperparameters.

    ``source`` names the mapping in errors; a relative ``hyperparams_file`` is read from
    ``base_dir`` (the space file's folder). A grace period that is not below the steps per
    trial is scaled to the trial (see ``fit_grace_period``, said in ``Sweep.notes``) when
    ``fit_early_stopping`` (the trial length came from the command line) or when the space
    does not set it; set in the space beside its own ``timesteps``, it is an error.
    """
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise SpaceError(f"{source}: unknown key(s) {', '.join(map(str, unknown))}; "
                         f"a space has {', '.join(KEYS)}")
    algo = data.get("algo", "ppo")
    if algo not in ALGOS:
        raise SpaceError(f"{source}: algo must be one of {', '.join(ALGOS)}, got {algo!r}")
    env = data.get("env", "SmartCar-v0")
    if not isinstance(env, str):
        raise SpaceError(f"{source}: env must be an env id such as SmartCar-v0, got {env!r}")
    vectorization = data.get("vectorization", "subproc")
    if vectorization not in VECTORIZATIONS:
        raise SpaceError(f"{source}: vectorization must be one of {', '.join(VECTORIZATIONS)}, "
                         f"got {vectorization!r}")
    engine = _mapping(data, "env_kwargs", source).get("engine")
    file = data.get("hyperparams_file")
    if file is not None:
        file = Path(file) if base_dir is None else base_dir / file
    try:  # the entry smartcar-train takes (a searched engine: the <env>-batched one)
        hyperparams = load_hyperparams(algo, env, file, variant=hyperparams_variant(
            vectorization, engine if isinstance(engine, str) else None))
    except (HyperparamsError, OSError) as err:
        raise SpaceError(f"{source}: hyperparams_file: {err}") from err
    overrides = _mapping(data, "hyperparams", source)
    if "n_timesteps" in overrides:
        raise SpaceError(f"{source}: hyperparams.n_timesteps: set the steps per trial with "
                         "timesteps: (or --timesteps)")
    hyperparams.update({k: parse_dimension(v, f"{source}: hyperparams.{k}")
                        for k, v in overrides.items()})
    env_kwargs = {k: parse_dimension(v, f"{source}: env_kwargs.{k}")
                  for k, v in _mapping(data, "env_kwargs", source).items()}
    timesteps = data.get("timesteps", hyperparams.pop("n_timesteps", None))
    hyperparams.pop("n_timesteps", None)
    sweep = Sweep(
        algo=algo, env=env, hyperparams=hyperparams, env_kwargs=env_kwargs,
        seed=parse_dimension(data.get("seed", 0), f"{source}: seed"),
        timesteps=_whole(timesteps, "timesteps", source, 1),
        num_samples=_whole(data.get("num_samples", 1), "num_samples", source, 1),
        cpus_per_trial=_whole(data.get("cpus_per_trial", preset_cpus(vectorization,
                                                                     hyperparams)),
                              "cpus_per_trial", source, 1),
        vectorization=vectorization,
        eval_freq=_whole(data.get("eval_freq", 10_240), "eval_freq", source, 1),
        eval_episodes=_whole(data.get("eval_episodes", 20), "eval_episodes", source, 1),
        eval_start=_whole(data.get("eval_start", 0), "eval_start", source, 0),
        random_seed=_whole(data.get("random_seed", 0), "random_seed", source, 0),
        source=str(source),
    )
    sweep.early_stopping = _asha(data.get("early_stopping"), sweep, source, fit_early_stopping)
    # What smartcar-train would fill in on the trial's node (its CPU count for n_envs): fixed
    # here, so that every trial's hyperparams.yaml is complete.
    sweep.hyperparams.setdefault("n_envs", sweep.cpus_per_trial)
    sweep.hyperparams.setdefault("policy", "MlpPolicy")
    check_sweep(sweep)
    return sweep


def preset_cpus(vectorization: str, hyperparams: dict[str, Any]) -> int:
    """The CPUs a trial's run uses (``cpus_per_trial``'s default): its process, plus the
    evaluation process of a batched run with ``eval_async``. A subproc run's ``n_envs``
    defaults to this instead (one env process per CPU)."""
    return 2 if vectorization == "batched" and hyperparams.get("eval_async") is True else 1


def check_sweep(sweep: Sweep) -> None:
    """Check the seeds, and every hyperparameter value a trial can get, with the same checks
    as ``smartcar-train`` (unknown or reserved names, bad values)."""
    seeds = sweep.seed.samples() if isinstance(sweep.seed, Dimension) else [sweep.seed]
    if (isinstance(sweep.seed, Dimension) and sweep.seed.kind in ("uniform", "loguniform")
            or not all(_is_int(s) for s in seeds)):
        raise SpaceError(f"{sweep.source}: seed must be a whole number or a dimension of whole "
                         f"numbers, got {_plain(sweep.seed)!r}")
    for hyperparams in trial_hyperparams_samples(sweep):
        try:
            run_int(hyperparams, "n_envs")
            normalize_kwargs(hyperparams.get("normalize"))
            discount(hyperparams)
            build_algo_kwargs(sweep.algo, hyperparams, n_actions=1)
        except HyperparamsError as err:
            raise SpaceError(f"{sweep.source}: hyperparams: {err}") from err


def trial_hyperparams_samples(sweep: Sweep) -> list[dict[str, Any]]:
    """Hyperparameters a trial can get: each dimension's sample values in turn, the others at
    their first (at most a few dozen mappings; not every combination)."""
    fixed = {k: (v.samples()[0] if isinstance(v, Dimension) else v)
             for k, v in sweep.hyperparams.items()}
    found = [fixed]
    for key, value in sweep.hyperparams.items():
        if isinstance(value, Dimension):
            found += [{**fixed, key: sample} for sample in value.samples()[1:]]
    return found


def env_kwargs_samples(sweep: Sweep) -> list[dict[str, Any]]:
    """Env keyword arguments a trial can get (each dimension's sample values in turn)."""
    dims = {k: v.samples() for k, v in sweep.env_kwargs.items() if isinstance(v, Dimension)}
    fixed = {k: v for k, v in sweep.env_kwargs.items() if not isinstance(v, Dimension)}
    first = {k: values[0] for k, values in dims.items()}
    found = [{**fixed, **first}]
    for key, values in dims.items():
        found += [{**fixed, **first, key: v} for v in values[1:]]
    return found


def apply_overrides(data: dict[str, Any], hyperparams: list[tuple[str, Any]] | None = None,
                    seeds: list[int] | None = None, **settings: Any) -> dict[str, Any]:
    """A copy of a space mapping with command-line values put in (None: not given)."""
    data = copy.deepcopy(data)
    if hyperparams:
        merged = dict(data.get("hyperparams") or {})
        merged.update(dict(hyperparams))
        data["hyperparams"] = merged
    if seeds:
        data["seed"] = {"grid": list(seeds)}
    data.update({k: v for k, v in settings.items() if v is not None})
    return data


def _asha(value: Any, sweep: Sweep, source: str | Path,
          fit: bool) -> dict[str, Any] | None:
    if value is None or value is False:
        return None
    if not isinstance(value, dict):
        raise SpaceError(f"{source}: early_stopping must be a mapping with {', '.join(ASHA_KEYS)}"
                         f" (ASHA) or null, got {value!r}")
    unknown = sorted(set(value) - set(ASHA_KEYS))
    if unknown:
        raise SpaceError(f"{source}: early_stopping: unknown key(s) {', '.join(unknown)}; "
                         f"expected {', '.join(ASHA_KEYS)}")
    grace = _whole(value.get("grace_period", 2 * sweep.eval_freq), "early_stopping.grace_period",
                   source, 1)
    factor = value.get("reduction_factor", 2)
    if not _is_number(factor) or factor <= 1:
        raise SpaceError(f"{source}: early_stopping.reduction_factor must be a number > 1, "
                         f"got {factor!r}")
    if grace < sweep.timesteps:
        return {"grace_period": grace, "reduction_factor": factor}
    if not fit and "grace_period" in value:
        raise SpaceError(f"{source}: early_stopping.grace_period ({grace}) must be below the "
                         f"steps per trial ({sweep.timesteps}), or no trial can be stopped; "
                         "lower it, or run every trial to the end with --no-early-stopping")
    fitted = fit_grace_period(sweep.timesteps, sweep.eval_freq, sweep.eval_start)
    if fitted is None:
        sweep.notes.append(
            f"no early stopping: early_stopping.grace_period ({grace}) is not below the "
            f"{sweep.timesteps} steps per trial, and a trial has no evaluation (every "
            f"{sweep.eval_freq} steps) in its first half to scale it to; "
            "every trial runs to the end (as with --no-early-stopping)")
        return None
    sweep.notes.append(
        f"early_stopping.grace_period {grace} is not below the {sweep.timesteps} steps per "
        f"trial: scaled to {fitted} (the last evaluation in a trial's first half); "
        "--no-early-stopping runs every trial to the end")
    return {"grace_period": fitted, "reduction_factor": factor}


def fit_grace_period(timesteps: int, eval_freq: int, eval_start: int = 0) -> int | None:
    """The grace period for trials of ``timesteps`` steps: the step of the last evaluation
    (ASHA compares trials at evaluations: multiples of ``eval_freq`` from ``eval_start`` on)
    within the first ``GRACE_FRACTION`` of a trial; None when there is none."""
    last = int(GRACE_FRACTION * timesteps) // eval_freq * eval_freq
    first = max(eval_freq, -(-eval_start // eval_freq) * eval_freq)
    return last if last >= first else None


def _mapping(data: dict[str, Any], key: str, source: str | Path) -> dict[str, Any]:
    value = data.get(key) or {}
    if not isinstance(value, dict):
        raise SpaceError(f"{source}: {key} must be a mapping of name -> value or dimension, "
                         f"got {value!r}")
    return value


def _whole(value: Any, key: str, source: str | Path, minimum: int) -> int:
    if value is None:
        raise SpaceError(f"{source}: {key} is not set (and the hyperparameter file has no "
                         "n_timesteps)" if key == "timesteps" else f"{source}: {key} is not set")
    if isinstance(value, float) and value == int(value):
        value = int(value)  # 2e5 in YAML
    if not _is_int(value) or value < minimum:
        raise SpaceError(f"{source}: {key} must be a whole number >= {minimum}, got {value!r}")
    return int(value)


def _is_int(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _plain(value: Any) -> Any:
    return value.to_yaml() if isinstance(value, Dimension) else value

