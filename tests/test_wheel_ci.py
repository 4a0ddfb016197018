"""docs/ci.md's jobs work as written: the wheel that ``python -m build`` makes from this checkout,
installed by the jobs' own install lines into a fresh virtualenv, passes the jobs' gate step.

Offline: the fresh virtualenv sees the dependencies this interpreter already has (a ``.pth``
file naming its site-packages) and pip runs with ``PIP_NO_INDEX``, so the install lines must be
satisfied by what is installed and by the wheel; nothing is downloaded.
"""

from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytest.importorskip("build", reason="the test extra brings build (python -m build)")
tomllib = pytest.importorskip("tomllib", reason="Python 3.11 reads pyproject.toml")

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "ci.md"
#: not part of a source tree: left out of the copy the wheel is built from
NOT_SOURCE = shutil.ignore_patterns(".git", ".venv*", "venv", "build", "dist", "runs", "site",
                                    "*.egg-info", "__pycache__", ".*_cache", ".hypothesis")


def _job_commands() -> list[str]:
    """The GitLab job's commands, checked to be the GitHub job's too (whitespace aside)."""
    blocks = re.findall(r"```yaml\n(.*?)```", DOC.read_text(), flags=re.S)
    jobs = {block.splitlines()[0].lstrip("# ").strip(): yaml.safe_load(block) for block in blocks}
    gitlab = jobs[".gitlab-ci.yml"]["policy-gate"]
    commands = [" ".join(c.split()) for c in gitlab["before_script"] + gitlab["script"]]
    (github,) = jobs[".github/workflows/policy-gate.yml"]["jobs"].values()
    runs = [line for step in github["steps"] if "run" in step
            for line in ([step["run"]] if step["run"].startswith("smartcar-eval")
                         else step["run"].splitlines())]
    assert [" ".join(c.split()) for c in runs] == commands
    return commands


def _run(argv: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    result = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"{argv}:\n{result.stdout[-3000:]}\n{result.stderr[-3000:]}"
    return result


@pytest.mark.slow
def test_the_ci_job_installs_the_built_wheel_and_its_gate_passes(tmp_path):
    commands = _job_commands()
    install = [c for c in commands if c.startswith("pip install")]
    (gate,) = [c for c in commands if c.startswith("smartcar-eval")]
    (line,) = [c for c in install if ".whl" in c]
    wheel_path = shlex.split(line)[2].partition("[")[0]          # wheels/smartcar_gym-V-...whl

    # the wheel, built from a copy of this checkout, where the job expects it
    project = tmp_path / "project"
    shutil.copytree(ROOT, tmp_path / "src", ignore=NOT_SOURCE)
    _run([sys.executable, "-m", "build", "--wheel", "--no-isolation", "--outdir",
          str((project / wheel_path).parent), str(tmp_path / "src")], tmp_path, dict(os.environ))
    built = [p.name for p in (project / wheel_path).parent.glob("*.whl")]
    assert built == [Path(wheel_path).name], f"docs/ci.md installs {wheel_path}, built: {built}"
    shutil.copytree(ROOT / "smartcar_gym" / "pretrained" / "mujoco", project / "policy")

    # a fresh virtualenv that sees this interpreter's dependencies but not its smartcar_gym
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()"
                           "['purelib'])"], capture_output=True, text=True, check=True)
    deps = [p for p in sys.path if p.endswith("site-packages")]
    Path(site.stdout.strip(), "dependencies.pth").write_text("\n".join(deps) + "\n")
    env = {key: value for key, value in os.environ.items() if key != "PYTHONPATH"}
    env.update(VIRTUAL_ENV=str(venv), PATH=f"{venv / 'bin'}{os.pathsep}{env['PATH']}",
               PIP_NO_INDEX="1", PIP_DISABLE_PIP_VERSION_CHECK="1", PYTHONWARNINGS="ignore")

    for command in install:                                  # pip of this venv, not the PATH's
        _run([str(python), "-m", *shlex.split(command)], project, env)
    where = _run([str(python), "-c", "import smartcar_gym; print(smartcar_gym.__file__)"],
                 project, env).stdout
    assert Path(where.strip()).is_relative_to(venv), where

    result = _run(["bash", "-c", gate], project, env)
    assert "pass mark held" in result.stdout + result.stderr
    record = json.loads((project / "eval.json").read_text())
    assert record["passed"] is True and record["vectorization"] == "batched"
