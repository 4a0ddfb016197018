"""``smartcar-eval --minari``: the evaluated episodes as a Minari dataset that Minari reads
back, whose env spec recovers the env (engine included) and whose returns are the
evaluation's records; existing ids, bad ids and a missing extra get one line."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

minari = pytest.importorskip("minari")
pytest.importorskip("h5py")
pytest.importorskip("stable_baselines3")

from smartcar_gym.agents.cli_eval import main as eval_main  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(autouse=True)
def datasets(tmp_path, monkeypatch) -> Path:
    root = tmp_path / "minari"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(root))
    return root


def _evaluate(tmp_path, *argv: str) -> dict:
    out = tmp_path / f"eval{len(list(tmp_path.glob('eval*.json')))}.json"
    assert eval_main([*argv, "--no-progress", "--json", str(out)]) == 0
    return json.loads(out.read_text())


@pytest.mark.slow
@pytest.mark.parametrize("vectorization, engine", [("subproc", "planar"),
                                                   ("batched", "planar"),
                                                   ("batched", "pybullet")])
def test_the_dataset_holds_the_evaluated_episodes(tmp_path, vectorization, engine):
    dataset_id = f"smartcar/default-{engine}-{vectorization}-v0"
    run = _evaluate(tmp_path, "--pretrained", "--engine", engine, "--episodes", "4",
                    "--vectorization", vectorization, "--minari", dataset_id)
    dataset = minari.load_dataset(dataset_id)
    records = run["episode_records"]
    assert dataset.total_episodes == 4
    assert dataset.total_steps == sum(r["length"] for r in records)
    for episode, record in zip(dataset.iterate_episodes(), records, strict=True):
        assert np.cumsum(episode.rewards)[-1] == record["episode_return"]  # summed in order
        assert len(episode.actions) == record["length"]
        assert episode.observations.shape == (record["length"] + 1, 21)
        assert episode.terminations[-1] or episode.truncations[-1]
        assert not (episode.terminations[:-1] | episode.truncations[:-1]).any()
        assert set(episode.infos) >= {"is_success", "distance", "pose", "odom_pose"}
        assert bool(episode.infos["is_success"][-1]) == record["success"]
        assert episode.infos["pose"].shape == (record["length"] + 1, 3)
        assert episode.infos["distance"][-1] == pytest.approx(record["final_distance_m"])
    env = dataset.recover_environment()
    try:
        assert env.spec.id == "SmartCar-v0" and env.spec.kwargs["engine"] == engine
        first = next(dataset.iterate_episodes())
        obs, _ = env.reset(seed=0)  # episode 0 is seed 0: the dataset's first observation
        np.testing.assert_array_equal(obs, first.observations[0])
    finally:
        env.close()
    meta = dataset.storage.metadata
    assert meta["ref_min_score"] < meta["ref_max_score"]
    assert meta["ref_max_score"] == pytest.approx(np.mean([r["episode_return"]
                                                           for r in records]))
    description = meta["description"]
    for said in ("shipped 'default'", f"engine {engine}", "seeds 0..3", "SmartCar-v0",
                 f"--vectorization {vectorization}"):
        assert said in description, said


@pytest.mark.slow
def test_recording_the_steps_leaves_the_records_as_they_were(tmp_path):
    argv = ["--pretrained", "--engine", "planar", "--episodes", "6",
            "--vectorization", "batched", "--n-envs", "4"]
    plain = _evaluate(tmp_path, *argv)
    recorded = _evaluate(tmp_path, *argv, "--minari", "smartcar/same-v0")
    assert plain["episode_records"] == recorded["episode_records"]


@pytest.mark.slow
def test_an_existing_id_is_kept_without_overwrite(tmp_path, capsys, datasets):
    _evaluate(tmp_path, "--random", "--engine", "planar", "--episodes", "2",
              "--vectorization", "batched", "--minari", "smartcar/kept-v0")
    with pytest.raises(SystemExit) as exit_info:
        eval_main(["--random", "--engine", "planar", "--episodes", "3",
                   "--minari", "smartcar/kept-v0"])
    assert exit_info.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        "smartcar-eval: error: --minari: the dataset smartcar/kept-v0 exists "
        f"({datasets / 'smartcar' / 'kept-v0'}); pass --overwrite to replace it")
    assert minari.load_dataset("smartcar/kept-v0").total_episodes == 2
    _evaluate(tmp_path, "--random", "--engine", "planar", "--episodes", "3",
              "--vectorization", "batched", "--minari", "smartcar/kept-v0", "--overwrite")
    dataset = minari.load_dataset("smartcar/kept-v0")
    assert dataset.total_episodes == 3
    assert "uniform random actions" in dataset.storage.metadata["description"]


@pytest.mark.parametrize("bad", ["no-version", "a b-v0", "smartcar/x-vv"])
def test_a_bad_id_is_one_line(capsys, bad):
    with pytest.raises(SystemExit):
        eval_main(["--random", "--episodes", "1", "--minari", bad])
    assert capsys.readouterr().err.strip().splitlines()[-1] == (
        f"smartcar-eval: error: --minari: {bad!r} is not a Minari dataset id: expected "
        "(namespace/)name-vN, e.g. smartcar/default-pybullet-v0 (letters, digits, - and _)")


def test_without_the_minari_extra_one_line_names_it():
    code = ("import sys\n"
            "class Blocker:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name.partition('.')[0] == 'minari':\n"
            "            raise ModuleNotFoundError(name)\n"
            "sys.meta_path.insert(0, Blocker())\n"
            "from smartcar_gym.agents.cli_eval import main\n"
            "sys.exit(main(['--random', '--episodes', '1', '--minari', 'smartcar/x-v0']))\n")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=120, cwd=ROOT,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert result.returncode == 2
    assert result.stderr.strip().splitlines()[-1] == (
        "smartcar-eval: error: --minari: minari not installed; Minari datasets need the "
        'minari extra: pip install "smartcar-gym[minari]"')


def test_overwrite_alone_is_refused(capsys):
    with pytest.raises(SystemExit):
        eval_main(["--random", "--episodes", "1", "--overwrite"])
    assert capsys.readouterr().err.strip().endswith("--overwrite: only with --minari")


def _refusal(capsys, argv: list[str]) -> str:
    """The one line ``smartcar-eval`` stops with (exit 2, no traceback)."""
    with pytest.raises(SystemExit) as exit_info:
        eval_main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err.strip().splitlines()[-1]


def _no_evaluation(monkeypatch) -> None:
    """Refusals come before any episode runs."""
    from smartcar_gym.agents import cli_eval

    def evaluate(*args, **kwargs):
        pytest.fail("the evaluation ran before the refusal")

    monkeypatch.setattr(cli_eval, "_evaluate", evaluate)


def _disk_full(monkeypatch) -> None:
    """The HDF5 file cannot be written: Minari has made the dataset's folder and metadata."""
    from minari.dataset._storages import get_minari_storage

    def update_episodes(self, episodes):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(get_minari_storage("hdf5"), "update_episodes", update_episodes)


RANDOM = ["--random", "--engine", "planar", "--vectorization", "batched", "--no-progress"]


def _entries(root: Path) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*"))


@pytest.mark.slow
def test_the_barn_policy_writes_its_dataset(tmp_path):
    # its env kwargs carry max_episode_steps, gym.make's keyword: the spec's field, not a kwarg
    run = _evaluate(tmp_path, "--pretrained", "barn", "--engine", "planar", "--episodes", "2",
                    "--minari", "test/barn-v0")
    dataset = minari.load_dataset("test/barn-v0")
    assert dataset.total_episodes == 2
    assert [len(e.actions) for e in dataset.iterate_episodes()] == [
        r["length"] for r in run["episode_records"]]
    spec = dataset.spec.env_spec
    assert spec.id == "SmartCarBARN-v0" and spec.max_episode_steps == 400
    assert "max_episode_steps" not in spec.kwargs and spec.kwargs["engine"] == "planar"
    env = dataset.recover_environment()
    try:
        assert env.spec.max_episode_steps == 400
    finally:
        env.close()


def test_the_spec_takes_gym_make_keywords_as_its_fields():
    from smartcar_gym.datasets.minari_writer import env_spec

    spec = env_spec("SmartCar-v0", {"engine": "planar", "max_episode_steps": 50})
    assert spec.max_episode_steps == 50 and spec.kwargs["engine"] == "planar"
    assert "max_episode_steps" not in spec.kwargs
    assert env_spec("SmartCar-v0", {"max_episode_steps": -1}).max_episode_steps is None
    registered = gym.spec("SmartCar-v0").max_episode_steps
    assert registered is not None and env_spec("SmartCar-v0", {}).max_episode_steps == registered


@pytest.mark.filterwarnings("error")
def test_a_failed_overwrite_keeps_the_old_dataset(tmp_path, capsys, monkeypatch, datasets):
    _evaluate(tmp_path, *RANDOM, "--episodes", "2", "--minari", "smartcar/kept-v0")
    before = _entries(datasets)
    _disk_full(monkeypatch)
    line = _refusal(capsys, [*RANDOM, "--episodes", "3", "--minari", "smartcar/kept-v0",
                             "--overwrite"])
    assert line == ("smartcar-eval: error: --minari: could not write the dataset "
                    "smartcar/kept-v0 (OSError: [Errno 28] No space left on device); the "
                    "datasets are as they were")
    assert _entries(datasets) == before  # no scratch folder left either
    assert minari.load_dataset("smartcar/kept-v0").total_episodes == 2


@pytest.mark.filterwarnings("error")
def test_a_failed_write_leaves_no_folder(capsys, monkeypatch, datasets):
    _disk_full(monkeypatch)
    _refusal(capsys, [*RANDOM, "--episodes", "2", "--minari", "smartcar/new-v0"])
    assert not (datasets / "smartcar" / "new-v0").exists()
    assert [p.name for p in datasets.iterdir() if p.name.startswith(".")] == []
    assert minari.list_local_datasets() == {}


@pytest.mark.filterwarnings("error")
def test_a_folder_that_is_no_dataset_is_never_replaced(capsys, monkeypatch, datasets):
    notes = datasets / "smartcar" / "mine-v0" / "notes.txt"
    notes.parent.mkdir(parents=True)
    notes.write_text("keep me")
    _no_evaluation(monkeypatch)
    line = _refusal(capsys, [*RANDOM, "--episodes", "2", "--minari", "smartcar/mine-v0",
                             "--overwrite"])
    assert line == (f"smartcar-eval: error: --minari: {notes.parent} exists and is not a "
                    "Minari dataset (no data/metadata.json); remove it or pick another id")
    assert notes.read_text() == "keep me"


@pytest.mark.filterwarnings("error")
def test_an_id_inside_a_dataset_is_refused(tmp_path, capsys, monkeypatch, datasets):
    _evaluate(tmp_path, *RANDOM, "--episodes", "1", "--minari", "smartcar/a-v0")
    _no_evaluation(monkeypatch)
    line = _refusal(capsys, [*RANDOM, "--episodes", "1", "--minari", "smartcar/a-v0/b-v0"])
    assert line == ("smartcar-eval: error: --minari: the dataset smartcar/a-v0/b-v0 would go "
                    f"inside the dataset smartcar/a-v0 ({datasets / 'smartcar' / 'a-v0'}); "
                    "pick another id")


@pytest.mark.slow
def test_empty_folders_left_by_an_older_write_need_overwrite(tmp_path, capsys, datasets):
    leftover = datasets / "smartcar" / "left-v0"
    (leftover / "data").mkdir(parents=True)
    line = _refusal(capsys, [*RANDOM, "--episodes", "1", "--minari", "smartcar/left-v0"])
    assert line == (f"smartcar-eval: error: --minari: {leftover} exists, empty folders with "
                    "no dataset in them; pass --overwrite to replace it")
    _evaluate(tmp_path, *RANDOM, "--episodes", "2", "--minari", "smartcar/left-v0",
              "--overwrite")
    assert minari.load_dataset("smartcar/left-v0").total_episodes == 2


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("under", ["", "sub"])
def test_a_datasets_path_through_a_file_is_one_line(tmp_path, capsys, monkeypatch, under):
    a_file = tmp_path / "datasets.txt"
    a_file.write_text("not a folder")
    value = str(a_file / under) if under else str(a_file)
    monkeypatch.setenv("MINARI_DATASETS_PATH", value)
    _no_evaluation(monkeypatch)
    line = _refusal(capsys, [*RANDOM, "--episodes", "1", "--minari", "smartcar/x-v0"])
    where = f"is under {a_file}, which is" if under else "is"
    assert line == (f"smartcar-eval: error: --minari: MINARI_DATASETS_PATH={value!r} {where} "
                    "a file, not a folder; expected the folder Minari keeps its datasets in")
    assert a_file.read_text() == "not a folder"


@pytest.mark.filterwarnings("error")
def test_an_empty_datasets_path_is_one_line(capsys, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", "")
    _no_evaluation(monkeypatch)
    assert _refusal(capsys, [*RANDOM, "--episodes", "1", "--minari", "smartcar/x-v0"]) == (
        "smartcar-eval: error: --minari: MINARI_DATASETS_PATH='' is empty; expected the "
        "folder Minari keeps its datasets in")
