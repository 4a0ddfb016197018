"""The planar batch's period in one compiled loop (``sim/planar/period.py``): every car's
boards, clock and physics end each step with the bits of the numpy loop over events
(``envs.vector.events.Clocks``), whatever the split over threads; a refused board raises the
numpy loop's error; the loop steps aside where it cannot run."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401
from smartcar_gym.sim.planar import dynamics, period
from smartcar_gym.sim.planar.layout import ANGLE

pytestmark = pytest.mark.skipif(not period.available(),
                                reason="numba (the fast extra) is not installed")


class Counted:
    """A batch's ``run_period`` that counts the periods it ran (``calls``: True each time
    the compiled loop ran them, False where it stepped aside)."""

    def __init__(self, cars) -> None:
        self.run, self.calls = cars.run_period, []

    def __call__(self, *args) -> bool:
        self.calls.append(self.run(*args))
        return self.calls[-1]


@pytest.fixture(autouse=True)
def every_size(monkeypatch) -> None:
    """The loop for batches of any size (from ``period.MIN_CARS`` cars in use)."""
    monkeypatch.setattr(period, "MIN_CARS", 1)


def make(num: int, fused: bool, threads: int = 1, env_id: str = "SmartCar-v0", **kwargs):
    """A planar batch, reset with seed 0; ``fused``: its periods in the compiled loop (else
    in ``Clocks``' numpy loop, the engine's ``run_period`` hidden from it)."""
    envs = gym.make_vec(env_id, num_envs=num, vectorization_mode="vector_entry_point",
                        engine="planar", max_episode_steps=25, num_threads=threads, **kwargs)
    envs.reset(seed=0)
    clocks = envs.unwrapped.clocks
    clocks.cars.run_period = Counted(clocks.cars) if fused else None
    return envs


def actions(num: int, steps: int) -> np.ndarray:
    """Random commands, every car stopped now and then (its board idles, then restarts)."""
    rng = np.random.default_rng(1)
    out = rng.uniform(-1, 1, (steps, num, 2)).astype(np.float32)
    out[rng.random((steps, num)) < 0.15] = 0.0
    return out


def numbers(envs) -> list[np.ndarray]:
    """Everything a period changes: the cars' states and drives, the boards' blocks, the
    clocks."""
    clocks = envs.unwrapped.clocks
    batch, base = clocks.cars.batch, clocks.base
    return [batch.state, batch.drive, base.floats, base.ints, base.flags,
            clocks.state.now_ns, clocks.next_update]


def assert_same(a, b) -> None:
    for x, y in zip(numbers(a), numbers(b), strict=True):
        assert x.dtype == y.dtype and np.array_equal(x.view(np.uint8), y.view(np.uint8))


def run_both(num: int, steps: int, threads: tuple[int, int] = (1, 1), **kwargs) -> tuple:
    fused, plain = make(num, True, threads[0], **kwargs), make(num, False, threads[1], **kwargs)
    for a in actions(num, steps):
        out_f, out_p = fused.step(a), plain.step(a)
        for x, y in zip(out_f[:4], out_p[:4], strict=True):
            assert np.array_equal(x, y)
        assert_same(fused, plain)
    return fused, plain


def test_every_car_ends_each_step_with_the_numpy_loops_bits() -> None:
    # 40 cars: two whole blocks of 16 and one with 8 padding lanes; episodes of 25 steps,
    # so cars reset at different points of the frame cycle
    fused, plain = run_both(40, 60)
    calls = fused.unwrapped.clocks.cars.run_period.calls
    assert len(calls) == 60 and all(calls)  # the compiled loop ran every period
    moved = fused.unwrapped.clocks.cars.batch.state[ANGLE]
    assert np.all(np.abs(moved) > 0)  # the wheels turned: the boards drove them
    fused.close()
    plain.close()


def test_a_split_over_two_threads_gives_the_same_bits() -> None:
    # 2,100 cars: 132 blocks, two chunks of at least MIN_CHUNK_BLOCKS on two threads
    assert 2100 // (period.MIN_CHUNK_BLOCKS * 16) >= 2
    fused, plain = run_both(2100, 6, threads=(2, 1))
    fused.close()
    plain.close()


@pytest.mark.parametrize("fused", [True, False])
def test_a_wheel_angle_with_no_count_is_refused_as_the_numpy_loop_refuses_it(fused) -> None:
    envs = make(20, fused)
    envs.step(actions(20, 1)[0])
    envs.unwrapped.clocks.cars.batch.state[ANGLE:ANGLE + 2, 7] = np.nan
    with pytest.raises(ValueError, match="gives no encoder count"):
        envs.step(actions(20, 2)[1])
    envs.close()


@pytest.mark.parametrize("fused", [True, False])
def test_a_board_due_forever_is_stopped_as_the_numpy_loop_stops_it(fused) -> None:
    envs = make(20, fused)
    envs.step(actions(20, 1)[0])
    base = envs.unwrapped.clocks.base
    base.frame_ms[3] = -1  # a view of its ints: due again at once
    with pytest.raises(RuntimeError, match="still due after 100 firings"):
        envs.step(np.full((20, 2), 0.5, dtype=np.float32))
    envs.close()


def test_it_steps_aside_where_numba_is_off_for_few_cars_or_with_a_laser(monkeypatch) -> None:
    envs = make(8, True)
    with monkeypatch.context() as patch:
        patch.setattr(dynamics, "COMPILED", False)
        assert not period.available()
        envs.step(actions(8, 1)[0])
    monkeypatch.setattr(period, "MIN_CARS", 9)
    envs.step(actions(8, 2)[1])
    monkeypatch.setattr(period, "MIN_CARS", 8)
    envs.step(actions(8, 3)[2])
    assert envs.unwrapped.clocks.cars.run_period.calls == [False, False, True]
    nav = make(4, True, env_id="SmartCarNav-v0")
    nav.step(actions(4, 1)[0])
    assert nav.unwrapped.clocks.cars.run_period.calls == []  # the laser's scans: numpy's
    envs.close()
    nav.close()
