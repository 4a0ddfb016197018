"""A period of the planar batch in one compiled loop: each car's board events and its physics
from event to event until the period's end, the cars split over threads by block.

``envs.vector.events.Clocks.run_period`` runs a period in numpy over every car at once: fire
the boards that are due (the controller's update, then the PID frame, then the motors'
drive), step every car to its next event, and again until each car reaches the end. Each car's
sequence depends only on its own numbers, so this loop runs the same sequence car by car:
for each pass of ``lanes.PASS`` blocks (256 cars), it fires each car's events
(``controller.compiled.fire_car``) and plans its substeps to its next event as
``events._plan`` does, sets the drive of the cars that fired (``drive.drive_cars``: a car's
drive depends only on its board's last outputs), and steps the pass in lanes
(``lanes.run_blocks``), until no car of the pass has time left. The arithmetic is those
functions', so every car ends the period with the numpy loop's bits
(``tests/test_planar_period.py``). What it saves is the numpy loop's fixed costs per event
(some 30 array operations and compiled calls over every car, four times a period) and the
split: the boards and motors run on every thread with the physics, one split a period
instead of one per event.

Where a car's board refuses to run (not reset, a wheel angle that gives no count, time going
backwards) or fires more than ``MAX_FIRINGS_PER_INSTANT`` times at one instant, its error is
raised once every chunk has run; the cars of the other passes have then run their period.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from smartcar_gym.controller import compiled as boards
from smartcar_gym.parallel import run_chunks
from smartcar_gym.sim.clock import BATCH_STILL_DUE, MAX_FIRINGS_PER_INSTANT, NS_PER_S
from smartcar_gym.sim.planar import drive, dynamics, lanes

if TYPE_CHECKING:
    from smartcar_gym.controller.batched import BatchedArbotix
    from smartcar_gym.sim.planar.batch import PlanarBatch

#: the code of a car still due after ``MAX_FIRINGS_PER_INSTANT`` firings at one instant
TOO_MANY = max(boards.MESSAGES) + 1
#: blocks per chunk below which splitting over threads costs more than it saves (1,024 cars,
#: as ``batch.MIN_CHUNK_CARS``)
MIN_CHUNK_BLOCKS = 1024 // lanes.LANES
#: cars from which a batch runs its periods here (``PlanarCars.run_period``). Below, the
#: numpy loop's fixed costs are small beside what compiling this loop costs a first run:
#: measured, the README's 64-car training from a cold cache took 39.8, 47.8 and 50.6 s
#: with this loop against 38.3, 42.4 and 42.5 s in numpy, in turn (numba compiles the loop
#: with the lanes and boards in it, and the evaluation process's head start on the boards'
#: loops is lost), for 0.18 ms a step saved warm (0.47 against 0.65 ms, 4,096 steps a
#: training; the same ``policy.pth`` either way). At 4,096 cars it saves 17 % of a step (8.2
#: against 10.2 ms).
MIN_CARS = 1024


def available() -> bool:
    """Whether this loop can run now: numba in use for the physics and the boards (read at
    each call: a test switches either off)."""
    return _run is not None and dynamics.COMPILED and boards.COMPILED


def run_period(batch: PlanarBatch, base: BatchedArbotix,
               encoders: tuple[np.ndarray, np.ndarray, np.ndarray],
               drive_tables: tuple[np.ndarray, ...], now: np.ndarray,
               next_update: np.ndarray, end: np.ndarray, pending: np.ndarray,
               period_ns: int, max_substep_ns: int) -> None:
    """Every ``pending`` car's events and substeps until ``end`` (ns on its clock ``now``,
    (N,) each, updated in place with ``next_update``; ``pending`` ends False): ``base``'s
    boards (hardware mode, ``base.compiled``), ``batch``'s physics, ``encoders`` the
    batch's ``joint_table`` of the encoder wheels' angles, ``drive_tables`` the motors'
    (``drive.drive_tables``)."""
    if not available():
        raise RuntimeError("period.run_period needs numba's loops (period.available())")
    n = batch.n
    steps, timestep = np.zeros(n, dtype=np.int64), np.zeros(n)
    fired = np.zeros(n, dtype=np.bool_)
    target = np.empty(n, dtype=np.int64)
    blocks, state, drive_rows = batch.blocks(), batch.state, batch.drive
    f, ints, flags = base.floats, base.ints, base.flags
    torque, damping = base.drive_torque, base.damping
    out_torque, out_damping = batch.torque, batch.damping
    never = np.iinfo(np.int64).max

    def work(first: int, last: int) -> None:  # a range of blocks (the loop frees the GIL)
        code = _run(first, last, state, blocks, batch.contact_groups, drive_rows, f, ints,
                    flags, torque, damping, out_torque, out_damping, *encoders, *drive_tables,
                    now, next_update, end, pending, steps, timestep, target, fired,
                    period_ns, max_substep_ns, never)
        if code == TOO_MANY:
            raise RuntimeError(BATCH_STILL_DUE)
        if code:
            error, message = boards.MESSAGES[code]
            raise error(message)

    run_chunks(work, len(blocks), batch.threads, MIN_CHUNK_BLOCKS)


_run = None
if dynamics.COMPILED and boards.COMPILED:
    import numba

    @numba.njit(cache=True, nogil=True)
    def _run(first, last, state, blocks, groups, drive_rows, f, ints, flags, torque, damping,
             out_torque, out_damping, enc_rows, enc_signs, enc_scale, held_group, held_side,
             held, damped_group, damped_side, damped, now, next_update, end, pending, steps,
             timestep, target, fired, period_ns, max_substep_ns, never):
        """``run_period`` for blocks ``first`` .. ``last - 1``; the code of the first car
        refused (0: none)."""
        cars = state.shape[1]
        for start in range(first, last, lanes.PASS):
            stop = min(start + lanes.PASS, last)
            lo, hi = start * lanes.LANES, min(stop * lanes.LANES, cars)
            while True:
                active = 0
                for i in range(lo, hi):
                    steps[i], timestep[i], fired[i] = 0, 0.0, False
                    if not pending[i]:
                        continue
                    # ``Clocks._fire``: the car's events due now, at most MAX a instant
                    due = now[i]
                    for k in range(MAX_FIRINGS_PER_INSTANT + 1):
                        if k == MAX_FIRINGS_PER_INSTANT:
                            return TOO_MANY
                        due = min(next_update[i],
                                  boards.next_frame_car(i, now[i], never, ints, flags))
                        if due > now[i]:
                            break
                        t = np.float64(now[i]) / np.float64(NS_PER_S)
                        left = (enc_signs[0] * state[enc_rows[0], i]) * enc_scale[0]
                        right = (enc_signs[1] * state[enc_rows[1], i]) * enc_scale[1]
                        update = now[i] >= next_update[i]
                        code = boards.fire_car(i, t, left, right, update, f, ints, flags)
                        if code:
                            return code
                        if update:
                            next_update[i] += period_ns
                        fired[i] = True
                    # ``events._plan``: its substeps to its next event, or the period done
                    if now[i] < end[i]:
                        active += 1
                        target[i] = min(due, end[i])
                        interval = target[i] - now[i]
                        if interval > 0:
                            count = -(-interval // max_substep_ns)
                            steps[i] = count
                            timestep[i] = np.float64(interval) / np.float64(count * NS_PER_S)
                    else:
                        pending[i] = False
                drive.drive_cars(fired, lo, hi, torque, damping, held_group, held_side, held,
                                 damped_group, damped_side, damped, out_torque, out_damping)
                if active == 0:
                    break
                lanes.run_blocks(state, blocks, groups, drive_rows, timestep, steps, start,
                                 stop)
                for i in range(lo, hi):
                    if pending[i]:
                        now[i] = target[i]
        return 0
