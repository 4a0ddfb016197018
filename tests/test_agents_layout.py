"""agents/ by concern: the package's module map names every module, the old module paths are
gone (each name they exported lives in one module of the new layout, which the commands use),
and the console scripts name the command-line modules."""

import importlib
import inspect
import re
from pathlib import Path

import pytest

import smartcar_gym.agents as agents

ROOT = Path(__file__).resolve().parent.parent
AGENTS = Path(agents.__file__).parent

# each removed module path, and where what it exported lives now: {new module: names}
MOVED = {
    "train": {"cli_train": ("main", "build_parser", "FAILED_EXIT_CODE",
                            "INTERRUPTED_EXIT_CODE"),
              "training": ("train",)},
    "evaluate": {"cli_eval": ("main", "build_parser", "summary_title"),
                 "eval_outputs": ("check_outputs", "count"),
                 "episodes": ("evaluate_policy_episodes",), "records": ("summarize",),
                 "models": ("load_model", "PRETRAINED_MODEL")},
    "rollouts": {"episodes": ("evaluate_policy_episodes", "ObservationShapeError"),
                 "records": ("EpisodeRecord", "summarize"),
                 "random_policy": ("RandomPolicy",), "policies": ("DEFAULT_ENV_ID",),
                 "video": ("record_video",)},
    "batched_rollouts": {"episodes": ("DEFAULT_BATCH", "RECORD_TOLERANCE", "act_batch",
                                      "evaluate_batched_episodes"),
                         "vec_envs": ("make_batched_env",)},
    "vec_env": {"sb3_vec_env": ("GymVectorVecEnv",), "vec_envs": ("make_batched_vec_env",)},
    "run_files": {"atomic_files": ("atomic_write_text", "file_mode", "save_model_atomic"),
                  "runs": ("CHECKPOINT_RE", "checkpoint_steps", "find_latest_checkpoint",
                           "replay_buffer_path_for")},
    "run_folder": {"runs": ("new_run", "resume_config", "new_config", "saved_models",
                            "REQUIRED_KEYS", "utc_timestamp", "_versions")},
    "model_files": {"models": ("PRETRAINED_MODEL", "PRETRAINED_POLICIES", "locate_model",
                               "load_model", "find_vecnormalize", "saved_algo",
                               "vecnormalize_path_for")},
    "zoo_folder": {"zoo_runs": ("read_zoo_run", "load_zoo_yaml", "Unreadable", "ZooRunError")},
}

# modules that stay but no longer re-export other modules' names: {module: (its own names,
# {the names' new module: names})}
NARROWED = {
    "env_factory": (("make_env", "check_env", "EnvSetupError", "INFO_KEYWORDS"),
                    {"vec_envs": ("make_vec_env", "close_vec_env", "wrap_normalize",
                                  "env_fns")}),
    "hyperparams": (("load_hyperparams",),
                    {"cli_args": ("key_value_arg", "non_negative_int_arg",
                                  "positive_int_arg"),
                     "atomic_files": ("output_path_error",)}),
}


def _defined_in(module, name: str) -> None:
    """``module.name`` exists, and a function or class is defined there (not re-exported)."""
    value = getattr(module, name)
    assert value is not None, f"{module.__name__}.{name}"
    if inspect.isfunction(value) or inspect.isclass(value):
        assert value.__module__ == module.__name__, f"{module.__name__}.{name}"


def test_the_module_map_names_every_module_of_the_package():
    named = set(re.findall(r"``(\w+)``", agents.__doc__))
    modules = sorted(p.stem for p in AGENTS.glob("*.py") if p.stem != "__init__")
    missing = [m for m in modules if m not in named]
    assert not missing, f"agents/__init__.py's module map does not name {missing}"


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_module_paths_are_gone(old):
    assert not (AGENTS / f"{old}.py").exists()
    with pytest.raises(ModuleNotFoundError, match=f"smartcar_gym.agents.{old}"):
        importlib.import_module(f"smartcar_gym.agents.{old}")


@pytest.mark.parametrize("old", sorted(MOVED))
def test_each_old_name_lives_in_its_new_module(old):
    for new, names in MOVED[old].items():
        module = importlib.import_module(f"smartcar_gym.agents.{new}")
        for name in names:
            _defined_in(module, name)


@pytest.mark.parametrize("kept", sorted(NARROWED))
def test_kept_modules_no_longer_re_export_other_modules_names(kept):
    module = importlib.import_module(f"smartcar_gym.agents.{kept}")
    own, elsewhere = NARROWED[kept]
    for name in own:
        assert getattr(module, name) is not None, f"{kept}.{name}"
    for new, names in elsewhere.items():
        home = importlib.import_module(f"smartcar_gym.agents.{new}")
        for name in names:
            _defined_in(home, name)
            assert not hasattr(module, name), f"{kept} still re-exports {name}"


def test_the_commands_use_the_library_s_objects():
    from smartcar_gym import extras
    from smartcar_gym.agents import cli_eval, episodes, random_policy, records, vec_envs, video

    assert cli_eval.evaluate_policy_episodes is episodes.evaluate_policy_episodes
    assert cli_eval.record_video is video.record_video
    assert not hasattr(episodes, "record_video")  # import it from agents.video
    assert video.evaluate_policy_episodes is episodes.evaluate_policy_episodes
    assert episodes.make_batched_env is vec_envs.make_batched_env
    assert cli_eval.summarize is records.summarize
    assert cli_eval.RandomPolicy is random_policy.RandomPolicy
    assert not hasattr(importlib.import_module("smartcar_gym.agents.env_factory"),
                       "make_vec_env")
    # missing_modules lives in smartcar_gym.extras; agents still exports it
    assert "missing_modules" in agents.__all__
    assert agents.missing_modules is extras.missing_modules
    assert not hasattr(agents, "moved")


def test_the_console_scripts_run_the_command_line_modules():
    tomllib = pytest.importorskip("tomllib", reason="Python 3.11 reads pyproject.toml")
    scripts = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["scripts"]
    # run: main in a process set up and ended by process_start.run_command
    assert scripts["smartcar-train"] == "smartcar_gym.agents.cli_train:run"
    assert scripts["smartcar-eval"] == "smartcar_gym.agents.cli_eval:run"
    for target in (scripts["smartcar-train"], scripts["smartcar-eval"]):
        module, _, name = target.partition(":")
        assert callable(getattr(importlib.import_module(module), name))
