"""smartcar-bench barn: the challenge's table, the JSON, the pass marks and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from smartcar_gym.bench.cli import main
from smartcar_gym.bench.report import summarize
from smartcar_gym.bench.runs import RunRecord, barn_jobs


def _run(argv: list[str], capsys) -> tuple[int, str, str]:
    """smartcar-bench's exit status (argparse's SystemExit's too), stdout and stderr."""
    try:
        return (main(argv), *capsys.readouterr())
    except SystemExit as exit_:
        return (exit_.code, *capsys.readouterr())


def _error(err: str) -> str:
    [line] = [x for x in err.splitlines() if x.startswith("smartcar-bench barn: error:")]
    return line.removeprefix("smartcar-bench barn: error: ")


def test_dwa_on_two_worlds_prints_the_table_writes_json_and_misses_a_mark(tmp_path, capsys):
    out_json, out_png = tmp_path / "dwa.json", tmp_path / "dwa.png"
    # world 228: DWA times out on MuJoCo, turning in front of a gap (docs/barn.md); 0: a success
    code, out, err = _run(["barn", "--driver", "dwa", "--engine", "mujoco", "--worlds", "0",
                           "228", "--json", str(out_json), "--plot", str(out_png),
                           "--fail-under", "60", "--max-final-distance", "5",
                           "--env-kwargs", "map_mode=known"], capsys)
    assert code == 1
    assert out.startswith("smartcar-bench barn: dwa on mujoco, 2 worlds x 1 run(s), seed 0\n")
    assert "| dwa | 2 | 0.500 | 0.000 | 0.500 | 0.000 |" in out
    assert "| move_base + DWA (Jackal), published | 50 x 10 | 0.88 |" in out
    assert "world   0 run 0: success after" in err
    assert "world 228 run 0: timeout after 1675 steps" in err
    assert ("smartcar-bench: pass mark missed: success rate 50.0% is under --fail-under 60% "
            "(2 episodes)") in err
    assert "pass mark held: mean final distance" in err
    data = json.loads(out_json.read_text())
    assert data["passed"] is False and data["engine"] == "mujoco" and data["worlds"] == [0, 228]
    assert [r["outcome"] for r in data["records"]] == ["success", "timeout"]
    assert data["success_rate"] == 0.5 and data["mean_score"] == pytest.approx(
        data["records"][0]["score"] / 2)
    assert data["mean_time_s"] == pytest.approx(data["records"][0]["time_s"])
    assert out_png.stat().st_size > 10_000


@pytest.mark.parametrize(("argv", "line"), [
    (["--worlds", "0", "300"], "BARN world 300 is out of range: the worlds are 0 to 299 ("),
    (["--driver", "teb"], "--driver: unknown driver 'teb'; the drivers are dwa"),
    (["--pretrained", "jackal"], "--pretrained: no shipped policy 'jackal'; the shipped ones "
                                 "are default, robust, nav, ros, mujoco, barn"),
    (["--env-kwargs", "lasr=1"], "cannot make SmartCarBARN-v0 with map_mode='laser', "
                                 "engine='mujoco', lasr=1, "
                                 "world_file=None: SmartCarBARN-v0 got an unexpected keyword "
                                 "argument 'lasr' (did you mean 'laser'?)"),
    (["--env-kwargs", "engine=planar"], "--env-kwargs: engine is set by --engine, not here"),
])
def test_bad_input_is_one_line(argv, line, capsys):
    code, _, err = _run(["barn", "--engine", "mujoco", *argv], capsys)
    assert code == 2 and _error(err).startswith(line)


def test_a_missing_or_corrupt_world_file_is_one_line(tmp_path, capsys):
    missing = tmp_path / "none.npz"
    code, _, err = _run(["barn", "--world-file", str(missing)], capsys)
    assert code == 2 and _error(err) == f"BARN world file {missing}: no such file"
    corrupt = tmp_path / "bad.npz"
    corrupt.write_text("no")
    code, _, err = _run(["barn", "--world-file", str(corrupt)], capsys)
    assert code == 2 and _error(err).startswith(f"BARN world file {corrupt}: not a readable npz")


def test_a_policy_for_another_observation_space_names_both_shapes(capsys):
    pytest.importorskip("stable_baselines3")
    code, _, err = _run(["barn", "--engine", "mujoco", "--pretrained", "nav", "--worlds", "0"],
                        capsys)
    assert code == 2
    assert _error(err) == ("pretrained:nav takes observations of shape (57,) (it was trained on "
                           "SmartCarNav-v0) but SmartCarBARN-v0 gives (59,): train a policy on "
                           "SmartCarBARN-v0")


def test_jobs_and_the_summary():
    jobs = barn_jobs([0, 6], runs=2, seed=5)
    assert [(j.world, j.run, j.seed) for j in jobs] == [(0, 0, 5), (0, 1, 6), (6, 0, 5),
                                                          (6, 1, 6)]
    records = [RunRecord(0, 0, 0, "success", 20.0, 0.4, 0.25, 8.0, 0.3, 200),
               RunRecord(0, 1, 1, "timeout", 160.0, 0.0, 0.0, 8.0, 2.0, 1675),
               RunRecord(6, 0, 0, "success", 40.0, 0.2, 0.2, 8.0, 0.4, 400, np.zeros((2, 2)))]
    summary = summarize(records)
    assert summary["success_rate"] == pytest.approx(2 / 3)
    assert summary["timeout_rate"] == pytest.approx(1 / 3) and summary["collision_rate"] == 0
    assert summary["mean_time_s"] == 30.0  # of the successful runs
    assert summary["mean_score"] == pytest.approx(0.2) and summary["n_worlds"] == 2
    assert "trajectory" not in records[2].to_dict()


def test_the_shipped_barn_policy_drives_two_test_worlds_at_the_top_score(tmp_path, capsys):
    """--pretrained barn on the planar batch, without a map: both runs succeed in about 10 s
    (100 steps) and score the challenge's maximum, 0.5 (AT within 2 OT); the policy's env
    kwargs come along (its laser map's, and its localization on its own scans)."""
    out = tmp_path / "barn.json"
    code = main(["barn", "--pretrained", "barn", "--engine", "planar", "--worlds", "0", "6",
                 "--n-envs", "2", "--fail-under", "100", "--json", str(out), "--quiet"])
    assert code == 0, capsys.readouterr().err
    result = json.loads(out.read_text())
    assert result["driver"] == "pretrained:barn" and result["vectorization"] == "batched"
    assert result["env_kwargs"]["map_mode"] == "laser"
    assert result["env_kwargs"]["planner_frequency"] == 0
    assert result["env_kwargs"]["localize"] is True  # its scans matched to its own map
    assert [r["outcome"] for r in result["records"]] == ["success", "success"]
    assert all(80 <= r["steps"] <= 140 and r["score"] == 0.5 for r in result["records"])


def test_the_protocol_runs_the_nominal_car_whatever_the_policy_learnt_with():
    """A policy's own env kwargs come along (its reward, moved to --engine), but not its
    randomisation, episode length or the other engine's keywords."""
    from argparse import Namespace

    from smartcar_gym.bench.cli import _env_kwargs

    learnt_with = {"progress": "path", "randomize": "odometry", "max_episode_steps": 400,
                   "engine": "planar", "planar_params": "mujoco"}
    kwargs = _env_kwargs(Namespace(engine="pybullet", world_file=None, env_kwargs=[]),
                         learnt_with)
    assert kwargs == {"progress": "path", "engine": "pybullet", "world_file": None}
    given = [("progress", "goal"), ("randomize", "odometry")]  # --env-kwargs: over them
    kwargs = _env_kwargs(Namespace(engine="mujoco", world_file=None, env_kwargs=given),
                         learnt_with)
    assert kwargs == {"progress": "goal", "engine": "mujoco", "randomize": "odometry",
                      "world_file": None}


def test_laser_noise_makes_a_worlds_runs_differ_and_the_json_says_so(tmp_path, capsys):
    """Deterministic engines repeat a world's runs; with ``--env-kwargs laser=...`` noise, run
    k's draws come from seed + k, so the runs differ, and the same command repeats them."""
    def runs(name, *extra):
        out = tmp_path / f"{name}.json"
        code = main(["barn", "--driver", "dwa", "--engine", "planar", "--worlds", "0",
                     "--runs", "2", "--n-envs", "2", "--json", str(out), "--quiet", *extra])
        assert code == 0, capsys.readouterr().err
        result = json.loads(out.read_text())
        return result, [(r["steps"], r["final_distance_m"]) for r in result["records"]]

    plain, plain_runs = runs("plain")
    # DWA runs the challenge's protocol unless told: no map
    assert plain_runs[0] == plain_runs[1]
    assert plain["env_kwargs"] == {"engine": "planar", "map_mode": "laser"}
    noise = ["--env-kwargs", "laser={noise_std_m: 0.01}"]
    noisy, noisy_runs = runs("noisy", *noise)
    assert noisy_runs[0] != noisy_runs[1]
    assert noisy["env_kwargs"] == {"engine": "planar", "map_mode": "laser",
                                   "laser": {"noise_std_m": 0.01}}
    # the known map when asked for, or when localize (scans matched to it) is
    for extra, mode in ((["map_mode=known"], "known"), (["localize=true"], None)):
        known, _ = runs("known", "--env-kwargs", *extra)
        assert known["env_kwargs"].get("map_mode") == mode
    assert runs("again", *noise)[1] == noisy_runs


def test_the_plot_draws_the_global_path_of_a_world_another_env_of_the_row_ran(tmp_path,
                                                                               capsys):
    """pybullet runs a row of single envs: world 6 runs on the second, and its panel still
    has its global path (plot_runs refuses a kept run without one)."""
    out = tmp_path / "row.png"
    code = main(["barn", "--pretrained", "barn", "--engine", "pybullet", "--worlds", "0", "6",
                 "--n-envs", "2", "--plot", str(out), "--quiet"])
    assert code == 0, capsys.readouterr().err
    assert out.stat().st_size > 10_000
    from smartcar_gym.bench.report import plot_runs
    from smartcar_gym.worlds.barn import load_worlds

    record = RunRecord(6, 0, 0, "success", 10.0, 0.5, 0.25, 5.0, 0.1, 100,
                       trajectory=np.zeros((2, 2)))
    with pytest.raises(ValueError, match=r"no global path for world\(s\) \[6\]"):
        plot_runs([record], load_worlds(), 0.42, tmp_path / "x.png", "t", {0: np.zeros((2, 2))})


class _Constant:
    """A driver that sends every car the same action (ahead: a run ends in a few steps)."""

    def __init__(self, action: tuple[float, float]) -> None:
        self.action = np.array(action, dtype=np.float32)

    def reset(self, cars, indices=None) -> None:
        pass

    def act(self, cars, obs, indices=None) -> np.ndarray:
        return np.tile(self.action, (len(obs), 1))


@pytest.fixture
def constant(monkeypatch):
    """``--driver dwa`` replaced by a constant action (set ``.action``)."""
    from smartcar_gym.bench import cli

    driver = _Constant((1.0, 0.0))
    monkeypatch.setattr(cli, "make_driver", lambda name: driver)
    return driver


def _world_file(tmp_path, indices, bad_start=False):
    from smartcar_gym.worlds.barn import load_worlds

    worlds = [load_worlds().world(i) for i in indices]
    centres = [w.centres for w in worlds] + ([np.array([[-2.0, 3.0]])] if bad_start else [])
    radii = [w.radii for w in worlds] + ([np.array([0.075])] if bad_start else [])
    paths = [w.path_cells for w in worlds] + ([worlds[0].path_cells] if bad_start else [])
    path = tmp_path / "worlds.npz"
    split = {"train_worlds": np.array([0])} if bad_start else {}  # the first reset's: world 0
    np.savez(path, centres=np.concatenate(centres), radii=np.concatenate(radii),
             offsets=np.cumsum([0] + [len(c) for c in centres]),
             paths=np.concatenate(paths), path_offsets=np.cumsum([0] + [len(p) for p in paths]),
             **split)
    return path


@pytest.mark.parametrize(("argv", "line"), [
    (["--worlds", "0", "0", "0"], "--worlds: world(s) 0 given more than once; each world is run "
                                  "--runs times"),
    (["--seed", "-1"], "argument --seed: "),
    (["--plot", "{tmp}/x.txt"], "--plot {tmp}/x.txt: matplotlib writes "),
    (["--plot", "{tmp}/x.png", "--plot-worlds", "6", "12"],
     "--plot-worlds: world(s) 6, 12 are not run"),
    (["--env-kwargs", "max_episode_steps=5"], "--env-kwargs: max_episode_steps is set by the "
                                              "protocol"),
    (["--goal-rate", "0"], "argument --goal-rate: expected a rate in Hz > 0, got '0'"),
    (["--goal-rate", "10", "--env-kwargs", "map_mode=known"],
     "--goal-rate: the goal is sent to move_base, which runs with map_mode=laser only"),
    (["--goal-rate", "10", "--env-kwargs", "localize=true"],
     "--goal-rate: the goal is sent to move_base, which runs with map_mode=laser only"),
    (["--goal-rate", "10", "--pretrained", "barn"],
     "--goal-rate: a classical driver's (move_base's goal); a policy takes its goal once"),
    (["--env-kwargs", "planner_frequency=0"],
     "--env-kwargs planner_frequency: a classical driver is move_base, whose planner runs at "
     "the challenge's rate"),
])
def test_bad_arguments_are_one_line_before_any_run(argv, line, tmp_path, constant, capsys):
    argv = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    code, out, err = _run(["barn", "--engine", "planar", "--worlds", "0", *argv], capsys)
    assert code == 2 and _error(err).startswith(line.replace("{tmp}", str(tmp_path)))
    assert "run 0:" not in err and out == "" and not list(tmp_path.iterdir())


def test_a_file_of_one_world_runs_its_own_test_world_on_one_car(tmp_path, constant,
                                                                 monkeypatch, capsys):
    from smartcar_gym.bench import cli

    made = []
    real = cli.make_batched_env
    monkeypatch.setattr(cli, "make_batched_env",
                        lambda env_id, n, kwargs: made.append(n) or real(env_id, n, kwargs))
    out_json = tmp_path / "out.json"
    code, out, err = _run(["barn", "--engine", "planar", "--world-file",
                           str(_world_file(tmp_path, [6])), "--n-envs", "2000", "--json",
                           str(out_json)], capsys)
    assert code == 0 and made == [1]
    assert out.startswith("smartcar-bench barn: dwa on planar, 1 worlds x 1 run(s), seed 0\n")
    data = json.loads(out_json.read_text())
    assert data["goal_rate_hz"] is None  # the goal sent once (--goal-rate: its rate)
    assert data["worlds"] == [0] and [r["world"] for r in data["records"]] == [0]
    assert data["records"][0]["outcome"] in ("success", "collision", "timeout", "failure")


def test_a_world_without_a_way_is_refused_before_the_first_run(tmp_path, constant, capsys):
    worlds = _world_file(tmp_path, [0], bad_start=True)
    code, _, err = _run(["barn", "--engine", "planar", "--world-file", str(worlds),
                         "--worlds", "0", "1"], capsys)
    assert code == 2 and "run 0:" not in err
    assert _error(err).startswith(f"BARN world 1 of {worlds} has no way for this car: the start "
                                  "[0.0, 0.0] is within ")


def test_a_world_failing_mid_run_keeps_the_runs_before_it(tmp_path, constant, monkeypatch,
                                                          capsys):
    from smartcar_gym.bench import cli

    monkeypatch.setattr(cli, "_plan_worlds", lambda *args: None)  # as if unchecked
    worlds, out_json = _world_file(tmp_path, [0], bad_start=True), tmp_path / "out.json"
    # the known map: a reset plans the world's path on it (without the map, from the laser)
    code, out, err = _run(["barn", "--engine", "planar", "--world-file", str(worlds),
                           "--worlds", "0", "1", "--json", str(out_json), "--env-kwargs",
                           "map_mode=known"], capsys)
    assert code == 2
    line = _error(err)
    assert line.startswith(f"BARN world 1 of {worlds} has no way for this car: the start ")
    assert line.endswith(f"(the 1 run(s) before it are kept in {out_json})")
    data = json.loads(out_json.read_text())
    assert [r["world"] for r in data["records"]] == [0] and data["passed"] is False
    assert data["error"].startswith("BARN world 1 of ")


def test_every_run_ends_with_an_outcome_whatever_the_top_speed(tmp_path, constant, capsys):
    constant.action = np.zeros(2, dtype=np.float32)  # stands: the run times out
    out_json = tmp_path / "out.json"
    code, _, err = _run(["barn", "--engine", "planar", "--worlds", "0", "--env-kwargs",
                         "max_linear=0.25", "--json", str(out_json)], capsys)
    assert code == 0 and "world   0 run 0: timeout after 3349 steps" in err
    assert [r["outcome"] for r in json.loads(out_json.read_text())["records"]] == ["timeout"]


def test_the_worlds_planned_over_threads_are_the_sequential_plans(tmp_path):
    """``_plan_worlds`` over two threads plans every chosen world as one thread does, to the
    bit, shares them with every task, and names the first chosen world without a way."""
    from types import SimpleNamespace

    import gymnasium as gym

    from smartcar_gym.bench import cli
    from smartcar_gym.worlds.barn import BarnWorldError

    worlds = _world_file(tmp_path, [0, 1, 2], bad_start=True)  # world 3: no way
    envs = [gym.make("SmartCarBARN-v0", engine="planar", world_file=str(worlds))
            for _ in range(3)]
    try:
        tasks = [env.unwrapped.task for env in envs]
        one = SimpleNamespace(tasks=lambda: tasks[:1])
        cli._plan_worlds(one, [2, 0, 1], threads=1)
        sequential = dict(tasks[0].planned_paths)
        tasks[0].planned_paths.clear()
        two = SimpleNamespace(tasks=lambda: tasks[1:])
        cli._plan_worlds(two, [2, 0, 1], threads=2)
        assert sorted(tasks[1].planned_paths) == [0, 1, 2] == sorted(sequential)
        for index, path in sequential.items():
            assert np.array_equal(tasks[1].planned_paths[index], path)
            assert tasks[2].planned_paths[index] is tasks[1].planned_paths[index]
        tasks[1].planned_paths.clear()
        with pytest.raises(BarnWorldError, match=f"^BARN world 3 of {worlds} has no way"):
            cli._plan_worlds(two, [0, 3, 1, 2], threads=2)
    finally:
        for env in envs:
            env.close()


@pytest.mark.parametrize(("given", "defaults"), [
    ([], {"map_mode": "laser"}),  # the challenge's protocol: no map
    ([("localize", True)], {}),  # localize alone: the known map, its scans matched to it
    ([("map_mode", "laser"), ("localize", True)], {"map_mode": "laser"}),  # its own scans
])
def test_a_classical_drivers_map_follows_localize_and_map_mode(given, defaults):
    from argparse import Namespace

    from smartcar_gym.bench.cli import driver_for

    args = Namespace(model=None, pretrained=None, driver="dwa", env_kwargs=given,
                     goal_rate=None)
    _, name, kwargs = driver_for(args, threads=1)
    assert name == "dwa" and kwargs == defaults
