"""The simulator owns the clock: event-driven stepping, substeps, and what depends on dt."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from git_trees import package_at

from smartcar_gym.calibration.maneuvers import hold, random_commands, run
from smartcar_gym.envs.robots import SmartCarRobot, drive
from smartcar_gym.sim.clock import seconds_to_ns
from smartcar_gym.sim.pybullet.simulator import Simulator

REPO = Path(__file__).resolve().parent.parent
ROUND_1 = "1103dff"  # the last commit with fixed 2 ms stepping (0.1.0)


class Recorder:
    """An event source that wants to act at given instants and records when it did."""

    def __init__(self, times_ns: list[int]) -> None:
        self.pending = sorted(times_ns)
        self.fired: list[int] = []

    def next_event_ns(self, now_ns: int) -> int | None:
        return self.pending[0] if self.pending else None

    def on_event(self, now_ns: int) -> None:
        while self.pending and self.pending[0] <= now_ns:
            self.pending.pop(0)
        self.fired.append(now_ns)


def test_intervals_are_split_into_the_fewest_equal_substeps(sim):
    probes: list[float] = []
    events = Recorder([34_000_000, 68_000_000, 102_000_000])
    sim.add_event_source(events)
    sim.run_until(seconds_to_ns(0.1), probe=probes.append)
    # 0-34 ms: 4 x 8.5 ms; 34-68: 4 x 8.5; 68-100: 4 x 8 ms; nothing is stepped past the end
    assert sim.physics_steps == 12
    assert events.fired == [34_000_000, 68_000_000]
    assert np.allclose(np.diff([0.0, *probes]), [0.0085] * 8 + [0.008] * 4)
    assert sim.time_step_s == pytest.approx(0.008)
    sim.run_until(seconds_to_ns(0.104))  # 100-102: one 2 ms step, 102-104: another
    assert events.fired[-1] == 102_000_000 and sim.physics_steps == 14
    assert sim.now_ns == 104_000_000


def test_events_at_the_end_act_before_run_until_returns(sim):
    events = Recorder([50_000_000])
    sim.add_event_source(events)
    sim.run_until(50_000_000)
    assert events.fired == [50_000_000]
    sim.run_until(50_000_000)  # nothing left at that instant
    assert events.fired == [50_000_000]


def test_time_cannot_go_back_and_a_stuck_source_is_named(sim):
    sim.run_until(10_000_000)
    with pytest.raises(ValueError, match="time cannot go back"):
        sim.run_until(5_000_000)

    class Stuck:
        def next_event_ns(self, now_ns: int) -> int:
            return now_ns

        def on_event(self, now_ns: int) -> None:
            pass

    sim.add_event_source(Stuck())
    with pytest.raises(RuntimeError, match=r"Stuck is still due after 100 firings"):
        sim.run_until(20_000_000)


def test_settle_steps_the_physics_before_time_starts(sim):
    sim.settle(0.1)
    assert sim.now_ns == 0 and sim.physics_steps == 10
    sim.run_until(1_000_000)
    with pytest.raises(RuntimeError, match=r"settle\(\) is for t = 0"):
        sim.settle(0.1)


@pytest.mark.parametrize("value", [0.0, -0.01, 0.05, 1e-6, float("nan"), "0.01", True, None])
def test_bad_substeps_are_refused(value):
    with pytest.raises(ValueError, match=r"max_substep_s must be a number of seconds in "
                                         r"\[0\.0001, 0\.02\]"):
        Simulator(max_substep_s=value)


def _schedule(robot: SmartCarRobot, commands) -> tuple[list[int], list[int]]:
    """Drive ``commands``; return the instants (ns) of board PID frames and controller updates."""
    frames: list[int] = []
    updates: list[int] = []
    base, on_event = robot.base, robot.on_event

    def recording(now_ns: int) -> None:
        f_time, then = base.board.f_time, base.controller.then
        on_event(now_ns)
        if base.board.f_time != f_time:
            frames.append(now_ns)
        if base.controller.then != then:
            updates.append(now_ns)

    robot.on_event = recording
    run(robot, commands)
    return frames, updates


def test_pid_frames_and_updates_happen_when_they_do_at_2_ms(shipped_model, shipped_config):
    """Random commands with stops: every PID frame and update at the same millisecond."""
    commands = random_commands(20.0, shipped_config.rate_hz, seed=3, stop_probability=0.3)
    assert commands.count((0.0, 0.0)) >= 20  # the board stops and re-arms several times
    schedules = {}
    for substep in (0.002, 0.01):
        sim = Simulator(max_substep_s=substep)
        robot = SmartCarRobot(sim, shipped_model, shipped_config)
        robot.spawn()
        schedules[substep] = _schedule(robot, commands)
        sim.close()
    frames, updates = schedules[0.01]
    assert schedules[0.002] == (frames, updates)
    assert updates == [100_000_000 * k for k in range(1, 201)]
    assert len(frames) > 400 and all(t % 1_000_000 == 0 for t in frames)
    assert 34_000_000 in np.diff(frames)  # frames 34 ms apart while moving


class Periodic:
    """Something acting every ``period_ns`` (a sensor, a publisher): it changes the steps."""

    def __init__(self, period_ns: int) -> None:
        self.period_ns = period_ns
        self.next_ns = period_ns

    def next_event_ns(self, now_ns: int) -> int:
        return self.next_ns

    def on_event(self, now_ns: int) -> None:
        self.next_ns += self.period_ns


def test_the_gearbox_friction_is_resent_when_the_step_changes(shipped_model, shipped_config,
                                                              monkeypatch):
    """pybullet stores a velocity motor's maxForce as force * dt: a coast-down shows it.

    The friction motor is set at spawn, at 10 ms steps. A 3 ms event source makes the coast
    run at 3 ms steps: re-sent, the friction is the same; kept, it is 10/3 times too strong.
    """

    def coast(extra_events: bool, resend: bool = True) -> float:
        world = Simulator()
        if not resend:
            monkeypatch.setattr(world, "_motors", _Frozen())
        robot = SmartCarRobot(world, shipped_model, shipped_config)
        robot.spawn()
        if extra_events:
            world.add_event_source(Periodic(3_000_000))
        samples = run(robot, hold((0.3, 0.0), 3.0, 10) + hold((0.0, 0.0), 0.6, 10))
        world.close()
        return samples[-1].speed  # 0.5 s after the stop reaches the board

    plain = coast(extra_events=False)
    assert plain == pytest.approx(0.151, abs=0.005)  # 0.32 m/s^2 of gearbox friction
    assert coast(extra_events=True) == pytest.approx(plain, rel=0.02)
    assert coast(extra_events=True, resend=False) < plain - 0.1  # stopped far too early


class _Frozen(dict):
    """A motor registry that forgets: nothing is re-sent when the step changes."""

    def __setitem__(self, key, value) -> None:
        pass


def test_the_chains_force_cap_never_binds(shipped_model, shipped_config):
    """Gear constraints are not re-sent on a dt change: their cap is far above their load.

    pybullet stores the 100 N m cap as an impulse at the step the chain is made with, the
    longest one (``max_substep_s``): at every shorter step the cap is higher still.
    """
    sim = Simulator()
    robot = SmartCarRobot(sim, shipped_model, shipped_config)
    robot.spawn()
    constraints = [sim.client.getConstraintUniqueId(i)
                   for i in range(sim.client.getNumConstraints())]
    assert len(constraints) == 2  # one chain per side
    peak = 0.0
    for twist in random_commands(10.0, 10, seed=5, max_linear=0.8, max_angular=4.0):
        drive(robot, *twist)
        for cid in constraints:
            peak = max(peak, float(np.max(np.abs(sim.client.getConstraintState(cid)))))
    sim.close()
    assert 0.0 < peak < 1.0  # N m, against a cap of at least 100



DIGEST = textwrap.dedent("""
    import hashlib, sys, warnings
    import gymnasium as gym, numpy as np
    import smartcar_gym
    warnings.simplefilter("ignore", DeprecationWarning)
    kwargs = eval(sys.argv[1])
    for env_id in ("SmartCar-v0", "SmartCarSim-v0"):
        for contact in ("sphere", "urdf"):
            env = gym.make(env_id, wheel_contact=contact, **kwargs)
            d = hashlib.sha256()
            obs, _ = env.reset(seed=1234)
            d.update(obs.tobytes())
            for a in np.random.default_rng(7).uniform(-1, 1, (60, 2)).astype(np.float32):
                obs, r, te, tr, info = env.step(a)
                d.update(obs.tobytes() + np.float64(r).tobytes() + info["pose"].tobytes())
                if te or tr:
                    d.update(env.reset()[0].tobytes())
            env.close()
            print(env_id, contact, d.hexdigest())
""")


@pytest.mark.slow
def test_2_ms_substeps_reproduce_round_1_bit_for_bit(tmp_path):
    """max_substep_s=0.002 is 0.1.0's fixed 500 Hz stepping: same observations, rewards, poses."""
    tree = package_at(ROUND_1, tmp_path, "round1")
    if tree is None:
        pytest.skip(f"git cannot give the round-1 code ({ROUND_1}) here")

    def digests(pythonpath: Path, kwargs: str) -> str:
        env = {**os.environ, "PYTHONPATH": str(pythonpath)}
        out = subprocess.run([sys.executable, "-c", DIGEST, kwargs], capture_output=True,
                             text=True, env=env, cwd=tmp_path, timeout=300, check=True)
        return out.stdout

    old = digests(tree, "{}")
    new = digests(REPO, "{'max_substep_s': 0.002}")
    assert len(old.splitlines()) == 4 and old == new
    assert new != digests(REPO, "{}")  # and the default stepping is another one
