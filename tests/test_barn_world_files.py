"""World files are data: checked once when loaded (one line naming the file, the array or the
world and what was expected), bounded in what they may declare, and their own split."""

from __future__ import annotations

import time
import warnings
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import smartcar_gym  # noqa: F401  (registers the ids)
from smartcar_gym.envs.tasks.barn import BarnTask
from smartcar_gym.navigation.grid_planner import MAX_CELLS, distance_grid
from smartcar_gym.worlds.barn import (
    MAX_ROWS,
    MAX_WORLDS,
    BarnWorldError,
    load_worlds,
)


def write_worlds(path: Path, worlds: list[tuple[np.ndarray, np.ndarray, np.ndarray]],
                 **arrays: np.ndarray) -> Path:
    """An npz of ``worlds`` (centres, radii, path cells each), ``arrays`` over its own."""
    out = {"centres": np.concatenate([w[0] for w in worlds]).reshape(-1, 2),
           "radii": np.concatenate([w[1] for w in worlds]),
           "offsets": np.cumsum([0] + [len(w[0]) for w in worlds]),
           "paths": np.concatenate([w[2] for w in worlds]).reshape(-1, 2),
           "path_offsets": np.cumsum([0] + [len(w[2]) for w in worlds])}
    np.savez(path, **{**out, **arrays})
    return path


def shipped(*indices: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    worlds = load_worlds()
    return [(worlds.world(i).centres, worlds.world(i).radii, worlds.world(i).path_cells)
            for i in indices]


def refusal(path: Path) -> str:
    """The one line loading ``path`` is refused with (warnings as errors)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(BarnWorldError) as err:
            load_worlds(path)
    line = str(err.value)
    assert "\n" not in line and line.startswith(f"BARN world file {path}: ")
    return line.removeprefix(f"BARN world file {path}: ")


def test_a_cylinder_outside_the_arena_is_refused_at_once(tmp_path):
    [(centres, radii, path)] = shipped(0)
    far = write_worlds(tmp_path / "far.npz", [(np.vstack([centres, [250.0, 250.0]]),
                                               np.append(radii, 0.075), path)])
    t = time.perf_counter()
    line = refusal(far)
    assert time.perf_counter() - t < 5.0
    assert line.startswith("world 0: a cylinder (centre [250.0, 250.0], radius 0.075) reaches "
                           "outside the arena, 12.5 m around the start (-2.0, 3.0)")


def test_a_grid_bigger_than_the_cap_is_one_line_before_it_is_made():
    t = time.perf_counter()
    with pytest.raises(ValueError, match=r"^a grid from \[-2000.0, -2000.0\] to \[2000.0, "
                                         r"2000.0\] at 0.02 m would have 4e\+10 cells, more "
                                         rf"than {MAX_CELLS:,}$"):
        distance_grid(np.zeros((1, 2)), np.ones(1), [-2000, -2000], [2000, 2000], 0.02)
    assert time.perf_counter() - t < 1.0


def _npy_declaring(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    """An .npy header declaring ``shape`` of ``descr``, with 16 bytes of data."""
    import io

    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, {"descr": descr, "fortran_order": False,
                                                  "shape": shape})
    return buffer.getvalue() + bytes(16)


def test_a_huge_declared_shape_is_refused_before_it_is_read(tmp_path):
    path = write_worlds(tmp_path / "huge.npz", shipped(0))
    huge = tmp_path / "huge2.npz"
    with zipfile.ZipFile(path) as src, zipfile.ZipFile(huge, "w") as dst:
        for name in src.namelist():
            data = src.read(name)
            dst.writestr(name, _npy_declaring((10 ** 12, 2)) if name == "centres.npy" else data)
    assert refusal(huge) == (f"centres declares 1000000000000 rows, more than the {MAX_ROWS} "
                             "a world file may have")


@pytest.mark.parametrize(("change", "line"), [
    ({"offsets": np.array([0.0, 181.0])}, "offsets must hold integers, got dtype float64"),
    ({"centres": np.array([[0.0, 1.0]], dtype=object)},
     "centres must hold integers or floats, got dtype object"),
    ({"centres": np.zeros((1, 3))}, "centres must have shape (n, 2), got (1, 3)"),
    ({"offsets": np.zeros(MAX_WORLDS + 2, dtype=int)},
     f"offsets declares {MAX_WORLDS + 2} rows, more than the {MAX_WORLDS + 1} a world file "
     "may have"),
    ({"test_worlds": np.array([0, 3])}, "test_worlds must be distinct worlds 0 to 0, at least "
                                        "one, got [0, 3] (2 values)"),
])
def test_arrays_of_the_wrong_kind_or_shape_are_one_line_naming_the_key(tmp_path, change, line):
    path = write_worlds(tmp_path / "w.npz", shipped(0), **change)
    assert refusal(path) == line


def test_worlds_without_cylinders_or_path_or_with_nan_are_refused_when_loaded(tmp_path):
    (c0, r0, p0), (c1, r1, p1) = shipped(0, 6)
    empty = write_worlds(tmp_path / "empty.npz", [(c0, r0, p0), (c1[:0], r1[:0], p1)])
    assert refusal(empty) == "world 1 has 0 cylinders; a world has 1 to 10000"
    no_path = write_worlds(tmp_path / "nopath.npz", [(c0, r0, p0[:0]), (c1, r1, p1)])
    assert refusal(no_path) == "world 0 has 0 path cells; a world has 1 to 10000"
    nan = c1.copy()
    nan[3, 1] = np.nan
    assert refusal(write_worlds(tmp_path / "nan.npz", [(c0, r0, p0), (nan, r1, p1)])) == (
        f"world 1: centres must be finite, got [{float(c1[3, 0])!r}, nan]")
    radii = r0.copy()
    radii[0] = -0.1
    assert refusal(write_worlds(tmp_path / "radius.npz", [(c0, radii, p0)])) == (
        "world 0: radii must be finite and > 0, got -0.1")
    crowded = np.zeros((10_001, 2))
    assert refusal(write_worlds(tmp_path / "crowded.npz", [(crowded, np.ones(10_001), p0)])) \
        == "world 0 has 10001 cylinders; a world has 1 to 10000"


def test_the_split_belongs_to_the_file(tmp_path):
    one = load_worlds(write_worlds(tmp_path / "one.npz", shipped(6)))
    assert len(one) == 1 and one.test_worlds == one.train_worlds == (0,)
    own = load_worlds(write_worlds(tmp_path / "own.npz", shipped(0, 6, 12),
                                   test_worlds=np.array([2]), train_worlds=np.array([0, 1])))
    assert own.test_worlds == (2,) and own.train_worlds == (0, 1)
    assert load_worlds().test_worlds[:3] == (0, 6, 12) and len(load_worlds().train_worlds) == 250


def test_a_single_env_draws_its_world_from_the_files_training_worlds(tmp_path):
    one = write_worlds(tmp_path / "one.npz", shipped(6))
    env = gym.make("SmartCarBARN-v0", engine="planar", world_file=one)
    try:
        _, info = env.reset(seed=0)
        assert info["world"] == 0
        assert np.allclose(env.unwrapped.task.world.centres, shipped(6)[0][0])
    finally:
        env.close()


@pytest.mark.parametrize(("world", "kind"), [("3", "str"), (2.5, "float"), (2.0, "float"),
                                             (True, "bool")])
def test_a_world_option_of_another_type_says_the_type_expected(world, kind):
    env = gym.make("SmartCarBARN-v0", engine="planar")
    try:
        with pytest.raises(BarnWorldError) as err:
            env.reset(seed=0, options={"world": world})
    finally:
        env.close()
    assert str(err.value).startswith(f"BARN world {world!r} is not a world index: expected an "
                                     f"integer 0 to 299, got {kind} (")


def test_numpy_numbers_and_bools_are_taken_and_bools_are_not_numbers():
    assert BarnTask(lookahead=np.float32(0.5)).lookahead_m == 0.5
    task = BarnTask(localize=np.True_)
    assert task.localize is True
    with pytest.raises(ValueError, match=r"^lookahead must be a distance > 0 m, got True$"):
        BarnTask(lookahead=True)
    with pytest.raises(ValueError, match=r"^localize must be True or False, got 1$"):
        BarnTask(localize=1)


def test_the_step_limit_follows_the_protocol():
    assert gym.spec("SmartCarBARN-v0").max_episode_steps is None  # the env ends every run
    env = gym.make("SmartCarBARN-v0", engine="planar", max_linear=0.25)
    try:
        env.reset(seed=0, options={"world": 0})
        assert env.unwrapped.task.timeout_steps == 3349
        steps, terminated, truncated = 0, False, False
        while not (terminated or truncated) and steps < 3350:
            _, _, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
            steps += 1
    finally:
        env.close()
    assert (steps, truncated, info["outcome"]) == (3349, True, "timeout")


@pytest.mark.parametrize("value", [3, "", b"worlds.npz", ["worlds.npz"]])
def test_a_world_file_that_is_no_path_is_one_line(value):
    with pytest.raises(TypeError, match=r"world_file must be a file path \(or None for the "
                                        f"shipped worlds\\), got {type(value).__name__}"):
        load_worlds(value)
