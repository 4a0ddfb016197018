"""move_base's recovery behaviours: its state machine over N robots, on a clock it is given.

ROS navigation (noetic-devel) ``move_base/src/move_base.cpp``, ``executeCycle`` and
``planThread``, one robot a row:

* CONTROLLING: a valid local command sets ``last_valid_control`` (and, when the last recovery
  was triggered by the controller, sets the recovery index back to 0); none, and
  ``controller_patience`` has passed since the last valid one, starts CLEARING (trigger
  CONTROLLING); none within the patience goes back to PLANNING. With ``oscillation_timeout >
  0``, not having moved ``oscillation_distance`` for that long starts CLEARING (trigger
  OSCILLATION).
* PLANNING: a new global plan goes back to CONTROLLING (and sets the index back to 0 when the
  trigger was PLANNING); no new plan for ``planner_patience`` starts CLEARING (trigger
  PLANNING).
* CLEARING, in the next cycle: runs behaviour ``index`` of (conservative reset, rotate,
  aggressive reset, rotate), then ``index += 1``, PLANNING, ``last_valid_plan`` and the
  oscillation timer set to now; with every behaviour run, the goal is aborted.
* A goal sent again (``goal_period``: the challenge's ``rostopic pub -r 10`` of its goal),
  ``executeCb``'s new goal: the index back to 0, PLANNING, ``last_valid_control``,
  ``last_valid_plan`` and the oscillation timer set to now, an aborted goal taken up again.
  So the patience never runs out and no behaviour runs. move_base's planner thread plans for
  the new goal while that cycle publishes nothing; here the cycle goes on with the plan the
  env made in the same step (a delay under one control cycle is not emulated). A rotation in
  place holds the goal until it ends (``runBehavior`` blocks ``executeCb``'s loop).

``Recoveries.step`` is one control cycle of the robots ``slots``: it says per robot what to do
(``CONTROL``: send the local planner's command; ``STOP``: zero; ``CONSERVATIVE`` /
``AGGRESSIVE``: clear the costmaps outside a square, then zero; ``ROTATE``: start a rotation in
place, which the caller runs and ends with ``rotated``; ``ROTATING``: go on with it;
``ABORTED``: zero from now on). Pure logic: numpy, no env.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# what a robot does this cycle (``Recoveries.step``)
CONTROL, STOP, CONSERVATIVE, AGGRESSIVE, ROTATE, ROTATING, ABORTED = range(7)
# the states
CONTROLLING, PLANNING, CLEARING, IN_RECOVERY, DONE = range(5)
# the triggers (move_base's RecoveryTrigger)
PLANNING_R, CONTROLLING_R, OSCILLATION_R = range(3)
#: move_base's default behaviours, in their order (``loadDefaultRecoveryBehaviors``)
BEHAVIOURS = (CONSERVATIVE, ROTATE, AGGRESSIVE, ROTATE)

# the challenge's move_base_params.yaml (the-barn-challenge, jackal_helper/configs/params)
CHALLENGE_CONTROLLER_PATIENCE_S = 15.0
CHALLENGE_PLANNER_PATIENCE_S = 5.0
CHALLENGE_OSCILLATION_TIMEOUT_S = 0.0  # 0: off
CHALLENGE_OSCILLATION_DISTANCE_M = 0.5
#: the challenge's move_base_DWA.launch sends its goal again at this rate (``rostopic pub -r
#: 10 /move_base_simple/goal``), Hz
CHALLENGE_GOAL_RATE_HZ = 10.0
#: move_base's conservative_reset_dist default (not set by the challenge)
CONSERVATIVE_RESET_M = 3.0
#: move_base's aggressive reset: 4 x the footprint's circumscribed radius
AGGRESSIVE_RESET_RADII = 4.0
#: rotate_recovery's defaults (not set by the challenge): sim_granularity (rad)
ROTATE_SIM_GRANULARITY = 0.017
#: rotate_recovery's tolerance: the local planner's yaw_goal_tolerance (the challenge's
#: base_local_planner_params.yaml; an angle, not scaled)
YAW_GOAL_TOLERANCE = 0.157


@dataclass(frozen=True)
class RecoveryConfig:
    """move_base's recovery parameters (s, m); the defaults are the challenge's (Jackal's,
    unscaled) with ROS's defaults where it sets none. ``aggressive_reset_m``: 4 x the
    circumscribed radius of the footprint (the challenge's padded 0.62 x 0.53 m: 1.631 m)."""

    controller_patience: float = CHALLENGE_CONTROLLER_PATIENCE_S
    planner_patience: float = CHALLENGE_PLANNER_PATIENCE_S
    oscillation_timeout: float = CHALLENGE_OSCILLATION_TIMEOUT_S
    oscillation_distance: float = CHALLENGE_OSCILLATION_DISTANCE_M
    conservative_reset_m: float = CONSERVATIVE_RESET_M
    aggressive_reset_m: float = AGGRESSIVE_RESET_RADII * float(np.hypot(0.31, 0.265))
    #: move_base's recovery_behavior_enabled
    enabled: bool = True
    #: s between two sendings of the goal (0: sent once)
    goal_period: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.goal_period) and self.goal_period >= 0.0):
            raise ValueError(f"goal_period must be a finite number of seconds >= 0 (0: the "
                             f"goal is sent once), got {self.goal_period!r}")

    @classmethod
    def challenge(cls, scale: float, speed_scale: float,
                  circumscribed_m: float | None = None,
                  goal_rate_hz: float | None = None) -> RecoveryConfig:
        """The challenge's set for a robot ``scale`` times as big, ``speed_scale`` times as
        fast (as ``DWAConfig.challenge``: lengths x scale, times x scale / speed_scale);
        ``circumscribed_m``: the robot's padded footprint's circumscribed radius (None: the
        challenge's, scaled); ``goal_rate_hz``: the goal sent again at this rate (the
        challenge's launch: ``CHALLENGE_GOAL_RATE_HZ``; its period scaled as the times),
        None: once."""
        base, time = cls(), scale / speed_scale
        return cls(goal_period=0.0 if goal_rate_hz is None else time / goal_rate_hz,
                   controller_patience=base.controller_patience * time,
                   planner_patience=base.planner_patience * time,
                   oscillation_timeout=base.oscillation_timeout * time,
                   oscillation_distance=base.oscillation_distance * scale,
                   conservative_reset_m=base.conservative_reset_m * scale,
                   aggressive_reset_m=(base.aggressive_reset_m * scale if circumscribed_m is None
                                       else AGGRESSIVE_RESET_RADII * circumscribed_m))


class Recoveries:
    """move_base's state machine for N robots (module docstring): ``reset(i, now, position)``
    when robot i gets its goal, then ``step`` once a control cycle."""

    def __init__(self, n: int, config: RecoveryConfig) -> None:
        self.config = config
        self.state = np.full(n, CONTROLLING)
        self.index = np.zeros(n, dtype=np.int64)
        self.trigger = np.full(n, PLANNING_R)
        self.last_valid_control = np.zeros(n)
        self.last_valid_plan = np.zeros(n)
        self.last_oscillation_reset = np.zeros(n)
        self.oscillation_pose = np.zeros((n, 2))
        #: when each robot's goal is sent again (inf: never)
        self.next_goal = np.full(n, np.inf)
        #: the behaviours each robot ran, in order (codes of ``BEHAVIOURS``)
        self.log: list[list[int]] = [[] for _ in range(n)]

    def reset(self, i: int, now: float, position: np.ndarray) -> None:
        """Robot ``i`` starts a goal at ``now`` at ``position`` (move_base's new goal) with
        its first global plan made (CONTROLLING: the env plans at its reset)."""
        self.state[i], self.index[i], self.trigger[i] = CONTROLLING, 0, PLANNING_R
        self.last_valid_control[i] = self.last_valid_plan[i] = now
        self.last_oscillation_reset[i] = now
        self.oscillation_pose[i] = position
        self.next_goal[i] = now + self.config.goal_period if self.config.goal_period else np.inf
        self.log[i] = []

    def step(self, slots: Sequence[int], now: np.ndarray, positions: np.ndarray,
             new_plan: np.ndarray, valid: np.ndarray) -> np.ndarray:
        """One cycle of robots ``slots`` at times ``now`` (K,) s, at ``positions`` (K, 2),
        with ``new_plan`` (K,) whether a new global plan came since the last cycle and
        ``valid`` (K,) whether the local planner found a command: what each does (K,)."""
        c = self.config
        out = np.full(len(slots), STOP)
        for k, i in enumerate(slots):
            t = float(now[k])
            if self.state[i] == IN_RECOVERY:  # move_base is inside runBehavior
                out[k] = ROTATING
                continue
            if t >= self.next_goal[i]:  # executeCb takes the goal sent again
                self.next_goal[i] += c.goal_period * (
                    math.floor((t - self.next_goal[i]) / c.goal_period) + 1)
                self.state[i], self.index[i] = PLANNING, 0
                self.last_valid_control[i] = self.last_valid_plan[i] = t
                self.last_oscillation_reset[i] = t
            if self.state[i] == DONE:
                out[k] = ABORTED
                continue
            if np.hypot(*(positions[k] - self.oscillation_pose[i])) >= c.oscillation_distance:
                self.last_oscillation_reset[i] = t
                self.oscillation_pose[i] = positions[k]
                if self.trigger[i] == OSCILLATION_R:
                    self.index[i] = 0
            if new_plan[k]:
                self.last_valid_plan[i] = t
                if self.trigger[i] == PLANNING_R:
                    self.index[i] = 0
                if self.state[i] == PLANNING:
                    self.state[i] = CONTROLLING
            if self.state[i] == CLEARING:
                out[k] = self._clear(i, t)
            elif self.state[i] == PLANNING:
                if t > self.last_valid_plan[i] + c.planner_patience:
                    self.state[i], self.trigger[i] = CLEARING, PLANNING_R
            else:  # CONTROLLING
                if (c.oscillation_timeout > 0.0
                        and t > self.last_oscillation_reset[i] + c.oscillation_timeout):
                    self.state[i], self.trigger[i] = CLEARING, OSCILLATION_R
                if valid[k]:
                    out[k] = CONTROL
                    self.last_valid_control[i] = t
                    if self.trigger[i] == CONTROLLING_R:
                        self.index[i] = 0
                elif t > self.last_valid_control[i] + c.controller_patience:
                    self.state[i], self.trigger[i] = CLEARING, CONTROLLING_R
                else:  # back to planning (overriding an oscillation's CLEARING, as there)
                    self.state[i] = PLANNING
                    self.last_valid_plan[i] = t
        return out

    def _clear(self, i: int, t: float) -> int:
        """CLEARING: the next behaviour (or the abort) of robot ``i`` at ``t``."""
        if not self.config.enabled or self.index[i] >= len(BEHAVIOURS):
            self.state[i] = DONE
            return ABORTED
        behaviour = BEHAVIOURS[self.index[i]]
        self.log[i].append(behaviour)
        if behaviour == ROTATE:
            self.state[i] = IN_RECOVERY
            return ROTATE
        self._ran(i, t)
        return behaviour

    def _ran(self, i: int, t: float) -> None:
        self.last_oscillation_reset[i] = self.last_valid_plan[i] = t
        self.state[i] = PLANNING
        self.index[i] += 1

    def rotated(self, i: int, now: float) -> None:
        """Robot ``i``'s rotation ended at ``now``: back to PLANNING, the next behaviour next."""
        self._ran(i, now)

    def reset_distance(self, action: int) -> float:
        """The side (m) of the square a clearing ``action`` keeps."""
        return (self.config.conservative_reset_m if action == CONSERVATIVE
                else self.config.aggressive_reset_m)


def rotation_speed(dist_left: np.ndarray, acc_lim: float, min_vel: float, max_vel: float
                   ) -> np.ndarray:
    """rotate_recovery's turn rate with ``dist_left`` (rad) to go: ``sqrt(2 acc_lim
    dist_left)`` within [min_in_place_vel_theta, max_vel_theta]."""
    return np.clip(np.sqrt(2.0 * acc_lim * np.asarray(dist_left, dtype=float)), min_vel,
                   max_vel)


def wrap(a: np.ndarray) -> np.ndarray:
    """Angles into [-pi, pi)."""
    return (np.asarray(a, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


class Rotations:
    """rotate_recovery's progress for N robots: ``start(i, heading)``, then ``left(i,
    heading)`` per cycle: the angle still to turn (rad), 0 when done (past the half turn and
    back within ``tolerance`` of the start heading)."""

    def __init__(self, n: int, tolerance: float) -> None:
        self.tolerance = tolerance
        self.start_angle = np.zeros(n)
        self.got_180 = np.zeros(n, dtype=bool)

    def start(self, i: int, heading: float) -> None:
        self.start_angle[i], self.got_180[i] = heading, False

    def left(self, i: int, heading: float) -> float:
        back = abs(float(wrap(heading - self.start_angle[i])))
        if self.got_180[i]:
            return 0.0 if back <= self.tolerance else back
        to_180 = abs(float(wrap(heading - self.start_angle[i] - np.pi)))
        if to_180 < self.tolerance:
            self.got_180[i] = True
        return np.pi + to_180
