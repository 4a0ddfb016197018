"""docs/ci.md: its GitHub Actions workflow and GitLab CI job pass check-jsonschema's own schemas
for them, install the CPU build of torch, cache pip and gate on a batched smartcar-eval whose
arguments smartcar-eval's parser takes."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from smartcar_gym.agents.cli_eval import build_parser

pytest.importorskip("check_jsonschema", reason="check-jsonschema is in the test extra")
tomllib = pytest.importorskip("tomllib", reason="Python 3.11 reads pyproject.toml")

DOC = Path(__file__).resolve().parent.parent / "docs" / "ci.md"
SCHEMAS = {".github/workflows/policy-gate.yml": "vendor.github-workflows",
           ".gitlab-ci.yml": "vendor.gitlab-ci"}
CPU_TORCH = "pip install torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu"
VERSION = tomllib.loads((DOC.parent.parent / "pyproject.toml").read_text())["project"]["version"]
#: where docs/ci.md's jobs take the package from: the wheel `python -m build` makes, kept in wheels/
WHEEL = f"wheels/smartcar_gym-{VERSION}-py3-none-any.whl"


def _blocks() -> dict[str, str]:
    """docs/ci.md's YAML blocks by the file name on their first line."""
    blocks = re.findall(r"```yaml\n(.*?)```", DOC.read_text(), flags=re.S)
    return {block.splitlines()[0].lstrip("# ").strip(): block for block in blocks}


def _check(path: Path, schema: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "check_jsonschema", "--builtin-schema", schema,
                           str(path)], capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("name", list(SCHEMAS))
def test_the_ci_file_passes_its_schema(name, tmp_path):
    text = _blocks()[name]
    path = tmp_path / Path(name).name
    path.write_text(text)
    result = _check(path, SCHEMAS[name])
    assert result.returncode == 0, result.stdout + result.stderr
    # the checker does check: the same file without its job's commands fails
    broken = text.replace("runs-on:", "runs_on:") if "github" in name \
        else text.replace("script:", "scripts:")
    path.write_text(broken)
    assert _check(path, SCHEMAS[name]).returncode == 1


@pytest.mark.parametrize("name", list(SCHEMAS))
def test_the_ci_file_installs_cpu_torch_caches_pip_and_gates_batched(name):
    data = yaml.safe_load(_blocks()[name])
    if "github" in name:
        (job,) = data["jobs"].values()
        python = next(s for s in job["steps"] if s.get("uses", "").startswith(
            "actions/setup-python"))
        assert python["with"]["cache"] == "pip"
        commands = [s["run"] for s in job["steps"] if "run" in s]
    else:
        job = data["policy-gate"]
        assert job["cache"]["paths"] == [".cache/pip"]
        assert job["variables"]["PIP_CACHE_DIR"] == "$CI_PROJECT_DIR/.cache/pip"
        commands = job["before_script"] + job["script"]
    lines = [line.strip() for command in commands for line in command.splitlines()]
    torch = next(i for i, line in enumerate(lines) if "torch" in line)
    package = next(i for i, line in enumerate(lines) if "smartcar_gym-" in line)
    assert lines[torch] == CPU_TORCH and torch < package  # CPU torch before the package
    # the wheel built from this checkout (smartcar-gym is not on PyPI), at its version
    assert lines[package] == f'pip install "{WHEEL}[train,mujoco]"', lines[package]
    assert not any("smartcar-gym" in line for line in lines if line.startswith("pip"))
    (gate,) = [c for c in commands if c.lstrip().startswith("smartcar-eval")]
    argv = shlex.split(" ".join(gate.split()))
    args = build_parser().parse_args(argv[1:])
    assert (args.vectorization, args.fail_under) == ("batched", 95.0)
