"""The planar engine's compiled stepping: ``dynamics.substep`` through numba, when installed.

numba is an optional extra (``pip install "smartcar-gym[fast]"``). Measured on the 2-core
machine (docs/planar.md): one substep of the smartcar takes about 22 us in Python floats and
0.6 us compiled, and a single env's physics is then a few percent of its step instead of two
thirds of it. The compiled loop runs ``dynamics.make_substep(math.sqrt)``, the very function
the Python and numpy paths run, and gives the same numbers bit for bit
(``tests/test_planar_dynamics.py``): no fast-math, no reordering.

``COMPILED`` says whether it is in use: numba importable and ``SMARTCAR_GYM_NUMBA`` not set to
``0`` (read at import). The functions are compiled on first use and cached on disk by numba.
"""

from __future__ import annotations

import math
import os

import numpy as np

from smartcar_gym.sim.planar.dynamics import make_substep

try:  # pragma: no branch - one of the two, per installation
    import numba
except ImportError:  # the fast extra is not installed: Python floats and numpy arrays
    numba = None

#: whether the compiled loops below are used (numba installed and not switched off)
COMPILED = numba is not None and os.environ.get("SMARTCAR_GYM_NUMBA", "1") != "0"

if COMPILED:
    _substep = numba.njit(cache=True)(make_substep(math.sqrt))

    @numba.njit(cache=True)
    def run_car(state: np.ndarray, car: np.ndarray, contacts: np.ndarray, groups: np.ndarray,
                drive: np.ndarray, dt: float, n: int) -> None:
        """``n`` substeps of ``dt`` s of one car (1D ``state``, ``car``, ``drive``; ``(K, 7)``
        ``contacts``), in place."""
        scratch = np.zeros((7, (car.shape[0] - 4) // 2))
        for _ in range(n):
            _substep(state, car, contacts, groups, drive, dt, scratch)

    @numba.njit(cache=True)
    def run_cars(state: np.ndarray, car: np.ndarray, contacts: np.ndarray, groups: np.ndarray,
                 drive: np.ndarray, dt: np.ndarray, n: np.ndarray) -> None:
        """Car i: ``n[i]`` substeps of ``dt[i]`` s; arrays in the batch's layout (``(S, N)``
        state, ``(P, N)`` car, ``(K, 7, N)`` contacts, ``(2G, N)`` drive), in place."""
        scratch = np.zeros((7, (car.shape[0] - 4) // 2))
        for i in range(state.shape[1]):
            if n[i] == 0:
                continue
            column, params = state[:, i], car[:, i]
            touches, motors, step = contacts[:, :, i], drive[:, i], dt[i]
            for _ in range(n[i]):
                _substep(column, params, touches, groups, motors, step, scratch)
else:
    run_car = run_cars = None
