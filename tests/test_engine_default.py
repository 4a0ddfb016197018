"""pybullet stays the default engine, and its rollouts are what they were before the engine
argument existed, bit for bit (the commit before it, extracted with ``git archive``)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from git_trees import package_at

REPO = Path(__file__).resolve().parent.parent
BEFORE_ENGINES = "1b9b166"  # the last commit before engine= (smartcar_gym/sim/clock.py)

DIGEST = textwrap.dedent("""
    import hashlib, sys
    import gymnasium as gym, numpy as np
    import smartcar_gym
    extra = eval(sys.argv[1])
    for env_id, kwargs in (("SmartCar-v0", {}), ("SmartCar-v0", {"randomize": "default"}),
                           ("SmartCarNav-v0", {}), ("SmartCarGoal-v0", {})):
        env = gym.make(env_id, **kwargs, **extra)
        d = hashlib.sha256()
        env.reset(seed=3)
        for a in np.random.default_rng(0).uniform(-1, 1, (40, 2)).astype(np.float32):
            obs, r, te, tr, info = env.step(a)
            obs = obs["observation"] if isinstance(obs, dict) else obs
            d.update(obs.tobytes() + np.float64(r).tobytes() + info["pose"].tobytes())
            if te or tr:
                env.reset()
        env.close()
        print(env_id, sorted(kwargs), d.hexdigest())
""")


def _digests(tree: Path, extra: str) -> str:
    done = subprocess.run([sys.executable, "-c", DIGEST, extra], capture_output=True, text=True,
                          cwd=tree, env={"PYTHONPATH": str(tree), "PATH": "/usr/bin:/bin"},
                          timeout=300, check=True)
    return done.stdout



@pytest.mark.slow
def test_pybullet_rollouts_are_unchanged_by_the_engine_argument(tmp_path):
    tree = package_at(BEFORE_ENGINES, tmp_path, "before")
    if tree is None:
        pytest.skip(f"needs git and commit {BEFORE_ENGINES} (a clone with its history)")
    before = _digests(tree, "{}")
    assert before.count("\n") == 4
    assert _digests(REPO, "{}") == before  # no engine given: pybullet
    assert _digests(REPO, "{'engine': 'pybullet'}") == before
