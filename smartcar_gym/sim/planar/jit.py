"""The planar engine's compiled stepping: ``dynamics.substep`` through numba, when installed.

numba is an optional extra (``pip install "smartcar-gym[fast]"``). Measured on the 2-core
machine (docs/planar.md): one substep of the smartcar takes about 22 us in Python floats and
0.6 us compiled, and a single env's physics is then a few percent of its step instead of two
thirds of it. The compiled loop runs ``dynamics.make_substep`` with ``math.sqrt``, the very
function the Python and numpy paths run, and gives the same numbers bit for bit
(``tests/test_planar_dynamics.py``): no fast-math, no reordering.

``COMPILED`` says whether it is in use: numba importable and ``SMARTCAR_GYM_NUMBA`` not set to
``0`` (read at import). The functions are compiled on first use and cached on disk by numba.
"""

from __future__ import annotations

from smartcar_gym.sim.planar.dynamics import COMPILED, run_car, run_cars

__all__ = ["COMPILED", "run_car", "run_cars"]
