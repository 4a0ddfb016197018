"""smartcar-tune's command line: one-line errors and exit code 2 for bad input, before any
trial starts (most before Ray starts)."""

from __future__ import annotations

import sys
import time

import pytest
import yaml

from smartcar_gym.scale import tune as tune_cli


@pytest.fixture(autouse=True)
def no_sweep(monkeypatch):
    """Every input here is bad: reaching the sweep (and Ray) is a failure, not a long run."""
    def refuse(*args, **kwargs):
        raise AssertionError("the bad input was not refused: a sweep started")

    monkeypatch.setattr(tune_cli, "ray_session", refuse)
    monkeypatch.setattr(tune_cli, "run_sweep", refuse)


def run(argv, capsys):
    code = tune_cli.main([str(a) for a in argv])
    return code, capsys.readouterr().err


def test_without_ray_one_line_names_the_extra(monkeypatch, capsys, tmp_path):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    code, err = run(["--out", tmp_path / "s"], capsys)
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("smartcar-tune: error: ray is not installed")
    assert 'pip install "smartcar-gym[ray]"' in err
    assert not (tmp_path / "s").exists()


def test_out_or_resume_is_required(capsys):
    with pytest.raises(SystemExit) as exit_:
        tune_cli.main([])
    assert exit_.value.code == 2
    assert "one of the arguments --out --resume is required" in capsys.readouterr().err


def test_num_cpus_is_for_a_local_instance(capsys, tmp_path):
    with pytest.raises(SystemExit) as exit_:
        tune_cli.main(["--address", "auto", "--num-cpus", "2", "--out", str(tmp_path)])
    assert exit_.value.code == 2
    assert "give one or the other" in capsys.readouterr().err


try:
    import ray.tune  # noqa: F401
    HAS_TUNE = True
except ImportError:
    HAS_TUNE = False
needs_tune = pytest.mark.skipif(not HAS_TUNE, reason='Ray Tune is not installed: pip install '
                                                     '"smartcar-gym[ray]"')


@needs_tune
@pytest.mark.parametrize(("space", "args", "message"), [
    ({"hyperparams": {"learning_rate": {"grid": []}}}, [],
     "hyperparams.learning_rate: {grid: ...} takes a non-empty list"),
    ({"hyperparams": {"learnin_rate": 1e-4}}, [], "unknown hyperparameter(s) for ppo"),
    ({"env_kwargs": {"goal_tolerance": {"grid": [0.1, -1.0]}}}, [],
     "env_kwargs: cannot make SmartCar-v0 with goal_tolerance=-1.0"),
    ({"timesteps": 1000}, [], "grace_period (30720) must be below the steps per trial (1000), "
     "or no trial can be stopped; lower it, or run every trial to the end with "
     "--no-early-stopping"),
    ({}, ["--hyperparams", "gamma={uniform: [0.9, 1.5]}"], "gamma must be a number in [0, 1]"),
])
def test_bad_spaces_exit_2_with_one_line(tmp_path, capsys, space, args, message):
    from smartcar_gym.scale.space import load_space

    data, _ = load_space()  # the shipped space, with one thing wrong
    for key, value in space.items():
        data[key] = {**data.get(key, {}), **value} if isinstance(value, dict) else value
    path = tmp_path / "space.yaml"
    path.write_text(yaml.safe_dump(data))
    code, err = run(["--space", path, *args, "--out", tmp_path / "s"], capsys)
    assert code == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "s").exists()  # nothing started


@needs_tune
def test_missing_space_file(tmp_path, capsys):
    code, err = run(["--space", tmp_path / "nope.yaml", "--out", tmp_path / "s"], capsys)
    assert code == 2 and "cannot read the search space" in err and "nope.yaml" in err


@needs_tune
def test_an_existing_sweep_is_not_overwritten_and_resume_needs_one(tmp_path, capsys):
    out = tmp_path / "s"
    out.mkdir()
    (out / "sweep.yaml").write_text("algo: ppo\n")
    code, err = run(["--out", out], capsys)
    assert code == 2 and f"{out} already holds a sweep; continue it with smartcar-tune " \
                          f"--resume {out}" in err
    code, err = run(["--resume", tmp_path / "other"], capsys)
    assert code == 2 and "sweep.yaml not found" in err
    code, err = run(["--resume", out], capsys)
    assert code == 2 and "holds no Ray Tune state" in err
    code, err = run(["--resume", out, "--timesteps", "100"], capsys)
    assert code == 2 and "--timesteps cannot be changed" in err


def test_a_uri_is_not_a_run_folder(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for option in ("--out", "--resume"):
        with pytest.raises(SystemExit) as exit_:
            tune_cli.main([option, "s3://bucket/sweep"])
        assert exit_.value.code == 2 and "not a URI" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@needs_tune
def test_an_out_folder_that_cannot_be_written(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    code, err = run(["--out", tmp_path / "file" / "sweep"], capsys)
    assert code == 2 and "--out: cannot create" in err and "is not a folder" in err


def _dead_address(monkeypatch) -> str:
    """An address nothing listens on, with the real ray_session in place."""
    import socket

    from smartcar_gym.scale import ray_session

    monkeypatch.setattr(tune_cli, "ray_session", ray_session.ray_session)  # the real one
    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        return f"127.0.0.1:{free.getsockname()[1]}"


@needs_tune
def test_an_address_nothing_listens_on_fails_at_once(tmp_path, capsys, monkeypatch):
    address = _dead_address(monkeypatch)
    start = time.monotonic()
    code, err = run(["--address", address, "--out", tmp_path / "s"], capsys)
    assert code == 2 and f"cannot connect to the Ray cluster at {address}" in err
    assert err.count("\n") == 1 and time.monotonic() - start < 30  # Ray alone: minutes
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize(("timesteps", "grace", "note"), [
    (4096, None, "smartcar-tune: note: no early stopping: early_stopping.grace_period (30720) "
                 "is not below the 4096 steps per trial"),
    (20480, 10240, "smartcar-tune: note: early_stopping.grace_period 30720 is not below the "
                   "20480 steps per trial: scaled to 10240"),
    (40960, 30720, None),
])
def test_a_quick_sweep_of_the_shipped_space_runs(timesteps, grace, note, tmp_path, capsys):
    """``smartcar-tune --timesteps 4096 --out sweep`` used to refuse the shipped space's
    grace_period (30720): now it runs, the grace period fitted to the trial, said in one line."""
    args = tune_cli.build_parser().parse_args(["--timesteps", str(timesteps),
                                                "--out", str(tmp_path / "s")])
    sweep, _ = tune_cli.new_sweep(args)  # what main runs before Ray starts
    err = capsys.readouterr().err
    assert sweep.timesteps == timesteps
    assert (sweep.early_stopping or {}).get("grace_period") == grace
    if note is None:
        assert err == ""
    else:
        assert err.count("\n") == 1 and err.startswith(note), err


@needs_tune
@pytest.mark.parametrize("engine", [[], ["--engine", "pybullet"]], ids=["default", "pybullet"])
def test_batched_trials_need_an_engine_that_batches(engine, tmp_path, capsys):
    code, err = run(["--vectorization", "batched", *engine, "--out", tmp_path / "s"], capsys)
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(
        "smartcar-tune: error: --vectorization batched: SmartCar-v0 with engine='pybullet' "
        if engine else "smartcar-tune: error: --vectorization batched: SmartCar-v0 with no env "
        "kwargs ")
    assert ("runs as a loop of single envs in one process, not a batch (engine='pybullet': it "
            "has no car batch (Engine.car_batch)); give an engine with a car batch (") in err
    assert "planar" in err and err.endswith("), or --vectorization subproc\n")
    assert not (tmp_path / "s").exists()


@needs_tune
def test_a_batched_space_on_an_engine_that_does_not_batch_names_the_file(tmp_path, capsys):
    space = tmp_path / "space.yaml"
    space.write_text(yaml.safe_dump({"vectorization": "batched",
                                     "env_kwargs": {"engine": {"grid": ["planar", "pybullet"]}}}))
    code, err = run(["--space", space, "--out", tmp_path / "s"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert err.startswith(f"smartcar-tune: error: {space}: vectorization: batched: SmartCar-v0 "
                          "with engine='pybullet' runs as a loop"), err


def test_an_unknown_vectorization_is_refused_by_name(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_:
        tune_cli.main(["--vectorization", "ray", "--out", str(tmp_path / "s")])
    assert exit_.value.code == 2
    assert "argument --vectorization: invalid choice: 'ray' (choose from subproc, batched)" in (
        capsys.readouterr().err.replace("'subproc', 'batched'", "subproc, batched"))


@needs_tune
def test_resume_keeps_the_vectorization(tmp_path, capsys):
    out = tmp_path / "s"
    out.mkdir()
    (out / "sweep.yaml").write_text("algo: ppo\n")
    code, err = run(["--resume", out, "--vectorization", "batched"], capsys)
    assert code == 2 and "--vectorization cannot be changed" in err


def test_ray_address_names_the_cluster_num_cpus_a_local_one(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("RAY_ADDRESS", "127.0.0.1:6379")
    with pytest.raises(SystemExit) as exit_:
        tune_cli.main(["--num-cpus", "2", "--out", str(tmp_path / "s")])
    assert exit_.value.code == 2
    assert ("--num-cpus sets the CPUs of a new local Ray instance; a running cluster "
            "(RAY_ADDRESS) has its own: give one or the other") in capsys.readouterr().err


@needs_tune
def test_a_ray_address_nothing_listens_on_says_where_it_came_from(tmp_path, capsys, monkeypatch):
    address = _dead_address(monkeypatch)
    monkeypatch.setenv("RAY_ADDRESS", address)
    code, err = run(["--out", tmp_path / "s"], capsys)
    assert code == 2 and err.count("\n") == 1
    assert err.startswith(f"smartcar-tune: error: cannot connect to the Ray cluster at "
                          f"{address}: ")
    assert err.endswith("(RAY_ADDRESS; unset it for a new local instance)\n")
    assert not (tmp_path / "s").exists()
