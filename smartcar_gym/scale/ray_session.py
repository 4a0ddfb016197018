"""Start a local Ray instance or connect to a cluster, and check CPUs before asking for them.

Ray does not fail when a request cannot be met: a Tune trial or an RLlib EnvRunner that
needs more CPUs than any node has waits forever (Tune warns after a minute, RLlib not at
all). ``check_cpus`` refuses such a request at once, naming the setting to change.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterator
from typing import Any

from smartcar_gym.scale import RAY_EXTRA

# Ray's setting of its workers' niceness (default 15), read by a raylet when it starts
WORKER_NICENESS_ENV = "RAY_worker_niceness"


class RayUnavailableError(RuntimeError):
    """Ray (or the part of it a command needs) is not installed, or the cluster cannot be
    reached; the message says which and what to do."""


class ResourceError(ValueError):
    """A request needs more CPUs than the Ray cluster has (it would wait forever)."""


def require_ray(*modules: str) -> None:
    """Import ``ray`` and ``modules`` (e.g. ``"ray.tune"``), or raise ``RayUnavailableError``
    naming the extra to install."""
    import importlib

    for name in ("ray", *modules):
        try:
            importlib.import_module(name)
        except ImportError as err:
            raise RayUnavailableError(
                f"{name} is not installed ({err}); install it with: {RAY_EXTRA}"
            ) from err


@contextlib.contextmanager
def ray_session(address: str | None = None, num_cpus: int | None = None,
                **init_kwargs: Any) -> Iterator[Any]:
    """A Ray instance for the body: a new local one (``num_cpus`` CPUs, default all) unless
    ``address`` names a running cluster (``"auto"``, ``"HOST:6379"``, ``"ray://HOST:10001"``).

    A local instance is always a fresh one (``address="local"``), so the address file of a
    crashed instance is never picked up, nor ``RAY_ADDRESS`` (a command that takes it, as
    ``smartcar-tune`` does, passes it as ``address``). Its workers (the trials,
    the EnvRunners: the work itself) run at the niceness of this process, not at Ray's nice
    15, unless ``RAY_worker_niceness`` is set: at nice 15 any other job on the machine starves
    them (a 20 s test sweep took over 15 minutes beside two busy loops). Ray is shut down after
    the body (the cluster keeps running when it was given by ``address``).
    """
    require_ray()
    import ray

    if address is not None and num_cpus is not None:
        raise ValueError("--num-cpus sets the CPUs of a new local Ray instance; a running "
                         "cluster (--address) has its own (give one or the other)")
    init_kwargs.setdefault("logging_level", logging.WARNING)
    if address is None:
        init_kwargs.setdefault("include_dashboard", False)
        if WORKER_NICENESS_ENV not in os.environ:
            system_config = dict(init_kwargs.pop("_system_config", None) or {})
            system_config.setdefault("worker_niceness", 0)
            init_kwargs["_system_config"] = system_config
        ray.init(address="local", num_cpus=num_cpus, **init_kwargs)
    else:
        probe(address)
        try:
            ray.init(address=address, **init_kwargs)
        except (ConnectionError, RuntimeError, ValueError) as err:
            first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
            raise RayUnavailableError(
                f"cannot connect to the Ray cluster at {address}: {first} (is `ray start "
                "--head` running there, and does this machine have its auth token?)"
            ) from err
    try:
        yield ray
    finally:
        ray.shutdown()


def probe(address: str, timeout_s: float = 10.0) -> None:
    """Refuse an explicit ``HOST:PORT`` (or ``ray://HOST:PORT``) nothing listens on: Ray itself
    retries such an address for minutes before it fails. Other forms (``auto``) are Ray's."""
    import socket

    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not host or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
    except OSError as err:
        raise RayUnavailableError(
            f"cannot connect to the Ray cluster at {address}: {err.strerror or err} (is `ray "
            "start --head` running there, and is the port open?)"
        ) from err


def node_cpus() -> list[float]:
    """CPUs of each alive node of the connected cluster, largest first."""
    import ray

    cpus = [float(node["Resources"].get("CPU", 0.0)) for node in ray.nodes() if node["Alive"]]
    return sorted(cpus, reverse=True)


def check_cpus(requests: list[float], what: str, setting: str) -> None:
    """Refuse CPU ``requests`` (one per actor: a trial, an EnvRunner, a learner) that the
    cluster's nodes cannot hold at once; ``what`` says what asks (e.g. "3 EnvRunners of 1
    CPU"), ``setting`` what to lower. Requests are packed onto the nodes' total CPUs largest
    first, as Ray places actors (an actor's CPUs are on one node)."""
    free = node_cpus()
    if not free:
        raise ResourceError("the Ray cluster has no alive node")
    largest = free[0]
    for need in sorted(requests, reverse=True):
        if need > largest:
            raise ResourceError(
                f"{what} needs {need:g} CPUs on one node, but the largest node of the Ray "
                f"cluster has {largest:g}; lower {setting} (Ray would wait forever)"
            )
        fit = next((i for i, cpus in enumerate(free) if cpus >= need), None)
        if fit is None:
            raise ResourceError(
                f"{what} need {sum(requests):g} CPUs at once, but the Ray cluster has "
                f"{sum(node_cpus()):g} ({', '.join(f'{c:g}' for c in node_cpus())} per node); "
                f"lower {setting} (Ray would wait forever for the rest)"
            )
        free[fit] -= need
