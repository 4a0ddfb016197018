"""controller.compiled.compile_loops: the boards' compiled loops made ahead, with the types a
batch gives them, so that the batch's own calls compile nothing more (checked in a fresh
process: the test process's loops may have been compiled by other tests)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

from smartcar_gym.controller import compiled

CHILD = textwrap.dedent("""
    import json, sys
    import numpy as np
    from smartcar_gym.controller import compiled

    LOOPS = ("_update_refused", "_update_cars", "_frames_refused", "_frame_cars",
             "next_frame_ns")

    def signatures():
        return {name: [str(s) for s in getattr(compiled, name).signatures] for name in LOOPS}

    made = compiled.compile_loops()
    ahead = signatures()
    import gymnasium as gym
    import smartcar_gym  # noqa: F401

    env = gym.make_vec("SmartCar-v0", num_envs=2, vectorization_mode="vector_entry_point",
                       engine="planar")
    env.reset(seed=0)
    for _ in range(10):  # driving: updates, frames and the next frames of both cars
        env.step(np.tile(np.float32([0.3, 0.5]), (2, 1)))
    env.close()
    json.dump({"made": made, "ahead": ahead, "after": signatures()}, sys.stdout)
""")


@pytest.mark.skipif(not compiled.COMPILED, reason="numba (the fast extra) is not installed")
def test_a_batch_compiles_no_board_loop_that_compile_loops_made_ahead():
    proc = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert out["made"] is True
    for name, ahead in out["ahead"].items():
        assert len(ahead) == 1, name  # each loop made once, by compile_loops
        assert out["after"][name] == ahead, f"the batch compiled {name} again"


def test_without_numba_there_is_nothing_to_compile(monkeypatch):
    monkeypatch.setattr(compiled, "COMPILED", False)
    assert compiled.compile_loops() is False
