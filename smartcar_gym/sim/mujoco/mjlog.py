"""MuJoCo's warnings through the facade: nothing is written to ``MUJOCO_LOG.TXT``.

Without a user warning handler, MuJoCo prints every warning and appends it to
``MUJOCO_LOG.TXT`` in the working folder. ``install`` (called when the facade is imported)
sets ours unless the process already has one. A warning raised inside ``step`` (the facade's
``mj_step``) is kept with a copy of that world's state as it was when MuJoCo noticed (NaN, inf
or huge values: it then resets the data to the model's initial state and carries on), for the
stepping code to report in one line naming the car (``describe``); any other warning (a model
compiled with an oddity, another library's world) becomes a Python ``MujocoWarning``.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np


class MujocoWarning(RuntimeWarning):
    """A warning from MuJoCo (its message), or the facade's report of an unstable world."""


@dataclass(frozen=True)
class Instability:
    """What MuJoCo said inside a step, and the world's state when it said it."""

    message: str
    time_s: float
    qpos: np.ndarray
    qvel: np.ndarray


_local = threading.local()  # per thread: the data being stepped, its warnings


def install() -> None:
    """Route MuJoCo's warnings here (unless the process has a handler of its own)."""
    if mujoco.get_mju_user_warning() is None:
        mujoco.set_mju_user_warning(_handle)


def _handle(message: str) -> None:
    data = getattr(_local, "data", None)
    text = " ".join(str(message).split())
    if data is None:
        warnings.warn(f"MuJoCo: {text}", MujocoWarning, stacklevel=2)
        return
    _local.caught.append(Instability(text, float(data.time), data.qpos.copy(),
                                     data.qvel.copy()))


def step(model: mujoco.MjModel, data: mujoco.MjData, nstep: int = 1) -> list[Instability]:
    """``mj_step(model, data, nstep)``; what MuJoCo warned meanwhile (usually nothing)."""
    _local.data, _local.caught = data, []
    try:
        mujoco.mj_step(model, data, nstep)
    finally:
        _local.data = None
    return _local.caught


def describe(event: Instability, bodies: Sequence[tuple[str, int, int]]) -> str:
    """One line: what MuJoCo said and where each named free body (name, qpos address, dof
    address) was and how fast it moved when it did."""
    states = []
    for name, q, v in bodies:
        x, y, z = event.qpos[q:q + 3]
        vx, vy, vz = event.qvel[v:v + 3]
        wx, wy, wz = event.qvel[v + 3:v + 6]
        states.append(f"{name} at x={x:.4g} y={y:.4g} z={z:.4g} m moving at vx={vx:.4g} "
                      f"vy={vy:.4g} vz={vz:.4g} m/s turning at {wx:.4g}, {wy:.4g}, {wz:.4g} "
                      "rad/s")
    where = "; ".join(states) or "no free body"
    said = event.message.split(". The simulation is unstable")[0]
    return (f"MuJoCo's simulation became unstable at t={event.time_s:.4f} s ({said}) "
            f"and MuJoCo reset that world to its initial state; {where}")
