"""The planar cars' motors: each side's output (the boards' ``drive_torque`` and ``damping``,
(N, 2)) shared into the wheel groups' drive rows with ``set_motor_output``'s and
``PlanarBody._drive``'s arithmetic in their order, as numba's loop over a range of the cars
(``PlanarCars.set_drive``, and each pass of ``period``'s loop). Without numba,
``PlanarCars.set_drive`` does the same sums on numpy arrays.
"""

from __future__ import annotations

import numpy as np

from smartcar_gym.sim.planar import dynamics

drive_cars = None


def drive_tables(held: list, damped: list, side: list[int], share: list[float],
                 sign: list[float]) -> tuple[np.ndarray, ...]:
    """``set_drive``'s joints as arrays for numba's loop: per held joint, in the order the
    body sums them, its wheel group and side, then the sign it turns with in its group, its
    share of the side's output and its wheel's forward sign; per damped joint its group and
    side, then its sign in the group and its share."""
    return (np.array([g for (g, _), _ in held], dtype=np.int64),
            np.array([side[k] for _, k in held], dtype=np.int64),
            np.array([(s, share[k], sign[k]) for (_, s), k in held],
                     dtype=np.float64).reshape(-1, 3),
            np.array([g for (g, _), _ in damped], dtype=np.int64),
            np.array([side[k] for _, k in damped], dtype=np.int64),
            np.array([(s, share[k]) for (_, s), k in damped], dtype=np.float64).reshape(-1, 2))


if dynamics.COMPILED:
    import numba

    @numba.njit(cache=True, nogil=True)
    def drive_cars(mask: np.ndarray, start: int, stop: int, torque: np.ndarray,
                   damping: np.ndarray, held_group: np.ndarray, held_side: np.ndarray,
                   held: np.ndarray, damped_group: np.ndarray, damped_side: np.ndarray,
                   damped: np.ndarray, out_torque: np.ndarray, out_damping: np.ndarray) -> None:
        """``set_drive``'s sums for each masked car of ``start`` .. ``stop - 1``
        (``torque``, ``damping``: (N, 2) by side; the outputs (G, N); the tables:
        ``drive_tables``)."""
        ng = out_torque.shape[0]
        tau = np.zeros(ng)
        damp = np.zeros(ng)
        for i in range(start, stop):
            if not mask[i]:
                continue
            tau[:] = 0.0
            damp[:] = 0.0
            for h in range(held_group.shape[0]):
                g = held_group[h]
                tau[g] = tau[g] + held[h, 0] * (torque[i, held_side[h]] * held[h, 1]
                                                * held[h, 2])
            for h in range(damped_group.shape[0]):
                g = damped_group[h]
                sign = damped[h, 0]
                damp[g] = damp[g] + sign * sign * (damping[i, damped_side[h]] * damped[h, 1])
            for g in range(ng):
                out_torque[g, i] = tau[g]
                out_damping[g, i] = damp[g]
