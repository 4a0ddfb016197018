"""Packaging: the env and smartcar-model work without the train extra; its CLIs say what is missing.

The torch-free install is emulated in a subprocess whose meta-path finder makes every module of
the ``train`` extra unimportable, as if it were not installed.
"""

from __future__ import annotations

import ast
import importlib.metadata
import os
import subprocess
import sys
import textwrap

from packaging.requirements import Requirement

# Import names of everything the train extra installs (and what SB3 brings with it).
TRAIN_ONLY = ("torch", "stable_baselines3", "tensorboard", "pandas", "matplotlib", "tqdm",
              "rich", "imageio_ffmpeg")

BLOCKER = textwrap.dedent(f"""
    import sys

    BLOCKED = {TRAIN_ONLY!r}

    class Blocker:
        def find_spec(self, name, path=None, target=None):
            if name.partition(".")[0] in BLOCKED:
                raise ModuleNotFoundError(f"No module named {{name!r}} (blocked)", name=name)
            return None

    sys.meta_path.insert(0, Blocker())
""")


def _run(body: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONWARNINGS": "ignore"}
    return subprocess.run([sys.executable, "-c", BLOCKER + textwrap.dedent(body)],
                          capture_output=True, text=True, timeout=120, env=env)


def test_core_requirements_leave_out_the_training_stack():
    core = [Requirement(r) for r in importlib.metadata.requires("smartcar-gym") or []]
    core_names = {r.name.lower() for r in core if r.marker is None}
    assert {"gymnasium", "pybullet", "numpy", "pyyaml", "xacro"} <= core_names
    heavy = {"torch", "stable-baselines3", "tensorboard", "pandas", "matplotlib", "tqdm", "rich",
             "imageio-ffmpeg"}
    assert not core_names & heavy
    train = {r.name.lower() for r in core
             if r.marker is not None and r.marker.evaluate({"extra": "train"})}
    assert heavy <= train


def test_env_and_smartcar_model_work_without_the_train_extra():
    result = _run("""
        import gymnasium as gym
        import numpy as np
        import smartcar_gym
        from smartcar_gym.model_cli import main as model_main

        env = gym.make("SmartCar-v0")
        obs, info = env.reset(seed=0)
        for _ in range(3):
            obs, reward, terminated, truncated, info = env.step(np.array([1.0, 0.0], np.float32))
        env.close()
        assert obs.shape == (21,) and np.isfinite(reward)
        status = model_main(["check"])
        loaded = sorted({m.partition(".")[0] for m in sys.modules} & set(BLOCKED))
        print("RESULT", status, loaded)
    """)
    assert result.returncode == 0, result.stderr
    assert "RESULT 0 []" in result.stdout


def test_cli_without_the_train_extra_prints_one_line_and_exits_2():
    result = _run("""
        import contextlib, io
        from smartcar_gym.agents import cli_eval, cli_train

        for main, argv in ((cli_train.main, ["--timesteps", "10"]),
                           (cli_eval.main, ["--pretrained"])):
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                try:
                    main(argv)
                except SystemExit as exit_:
                    print("EXIT", exit_.code)
            print("STDERR", repr(err.getvalue()))
    """)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0] == "EXIT 2" and lines[2] == "EXIT 2"
    train_err, eval_err = (ast.literal_eval(line.removeprefix("STDERR ")) for line in lines[1::2])
    for prog, err in (("smartcar-train", train_err), ("smartcar-eval", eval_err)):
        assert err.count("\n") == 1, err
        assert err.startswith(f"{prog}: error: stable_baselines3, torch")
        assert err.rstrip().endswith('pip install "smartcar-gym[train]"')
