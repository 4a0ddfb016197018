"""agents/ by concern: the package's module map names every module, the old module paths still
import what they exported, and the console scripts name the command-line modules."""

import importlib
import re
from pathlib import Path

import pytest

import smartcar_gym.agents as agents

ROOT = Path(__file__).resolve().parent.parent
AGENTS = Path(agents.__file__).parent

# what each old module path exported, as earlier code and the docs import it
OLD_NAMES = {
    "train": ("main", "build_parser", "FAILED_EXIT_CODE", "INTERRUPTED_EXIT_CODE", "train"),
    "evaluate": ("main", "build_parser", "check_outputs", "evaluate_policy_episodes",
                 "load_model", "summarize", "count", "summary_title", "PRETRAINED_MODEL"),
    "rollouts": ("EpisodeRecord", "RandomPolicy", "evaluate_policy_episodes", "record_video",
                 "summarize", "ObservationShapeError", "DEFAULT_ENV_ID"),
    "batched_rollouts": ("DEFAULT_BATCH", "RECORD_TOLERANCE", "act_batch",
                         "evaluate_batched_episodes", "make_batched_env"),
    "vec_env": ("GymVectorVecEnv", "make_batched_vec_env"),
    "env_factory": ("make_env", "check_env", "EnvSetupError", "make_vec_env", "close_vec_env",
                    "wrap_normalize", "env_fns", "INFO_KEYWORDS"),
    "hyperparams": ("key_value_arg", "non_negative_int_arg", "positive_int_arg",
                    "output_path_error", "load_hyperparams"),
    "run_files": ("atomic_write_text", "file_mode", "save_model_atomic", "CHECKPOINT_RE",
                  "checkpoint_steps", "find_latest_checkpoint", "replay_buffer_path_for"),
    "run_folder": ("new_run", "resume_config", "new_config", "saved_models", "REQUIRED_KEYS",
                   "utc_timestamp", "_versions"),
    "model_files": ("PRETRAINED_MODEL", "PRETRAINED_POLICIES", "locate_model", "load_model",
                    "find_vecnormalize", "saved_algo", "vecnormalize_path_for"),
    "zoo_folder": ("read_zoo_run", "load_zoo_yaml", "Unreadable", "ZooRunError"),
}


def test_the_module_map_names_every_module_of_the_package():
    named = set(re.findall(r"``(\w+)``", agents.__doc__))
    modules = sorted(p.stem for p in AGENTS.glob("*.py") if p.stem != "__init__")
    missing = [m for m in modules if m not in named]
    assert not missing, f"agents/__init__.py's module map does not name {missing}"


@pytest.mark.parametrize("old", sorted(OLD_NAMES))
def test_old_module_paths_still_import_their_names(old):
    module = importlib.import_module(f"smartcar_gym.agents.{old}")
    for name in OLD_NAMES[old]:
        assert getattr(module, name) is not None, f"{old}.{name}"
    with pytest.raises(AttributeError):
        module.no_such_name  # noqa: B018


def test_an_old_name_is_the_object_of_its_new_module():
    from smartcar_gym.agents import cli_eval, episodes, rollouts, vec_envs, video

    assert rollouts.evaluate_policy_episodes is episodes.evaluate_policy_episodes
    assert rollouts.record_video is episodes.record_video is video.record_video
    assert cli_eval.main is cli_eval.main
    assert importlib.import_module("smartcar_gym.agents.env_factory").make_vec_env is (
        vec_envs.make_vec_env)


def test_the_console_scripts_run_the_command_line_modules():
    tomllib = pytest.importorskip("tomllib", reason="Python 3.11 reads pyproject.toml")
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["smartcar-train"] == "smartcar_gym.agents.cli_train:main"
    assert scripts["smartcar-eval"] == "smartcar_gym.agents.cli_eval:main"
    for target in (scripts["smartcar-train"], scripts["smartcar-eval"]):
        module, _, name = target.partition(":")
        assert callable(getattr(importlib.import_module(module), name))
