"""``smartcar-calibrate``: it recovers a known effective track and a mis-set ticks_meter."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from smartcar_gym.calibration import cli
from smartcar_gym.calibration.drives import Plan, Run
from smartcar_gym.calibration.estimate import (
    CalibrationError,
    RunError,
    fit,
    integrate,
    umbmark_error,
)
from smartcar_gym.calibration.procedure import calibrate
from smartcar_gym.calibration.yaml_edit import calibrated_text
from smartcar_gym.controller import load_controller_config, parse_controller_config
from smartcar_gym.controller.config_yaml import default_config_path
from smartcar_gym.envs.robots.variation import Variation
from smartcar_gym.model import load_model

# The sphere-wheel car turns as if its track were 0.329 m (10 s spins at 1 rad/s with
# base_width 0.33: odometry within 0.25 % of the true turn; docs/sim2real.md).
EFFECTIVE_TRACK_M = 0.329
SHORT = Plan(straight_m=1.0, spin_revolutions=1.0, square_side_m=0.5)  # a faster test


def _mis_set_yaml(tmp_path, base_width="0.26", ticks_meter="4100"):
    text = Path(default_config_path()).read_text(encoding="utf-8")
    text = text.replace("    base_width: 0.26\n", f"    base_width: {base_width}\n")
    text = text.replace("    ticks_meter: 4100\n", f"    ticks_meter: {ticks_meter}\n")
    path = tmp_path / "mis_set.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("fit_name", ["spin", "umbmark", "all"])
def test_calibration_recovers_the_effective_track_from_a_mis_set_yaml(shipped_model, tmp_path,
                                                                      fit_name):
    config = load_controller_config(_mis_set_yaml(tmp_path, base_width="0.20"))
    result = calibrate(shipped_model, config, SHORT, fit_name)
    assert result.base_width_m == pytest.approx(EFFECTIVE_TRACK_M, rel=0.05)
    assert result.ticks_meter == pytest.approx(4100, rel=0.05)
    # odometry was badly wrong before (the squares' ends 1.28 m off), and is right after
    # (0.3-3.2 cm: 0.4 % of track error is 2.5 cm on a square of 4 turns)
    assert umbmark_error(result.before) > 1.0
    assert umbmark_error(result.after) < 0.04
    spins_after = [RunError.of(r).relative for r in result.after if r.name.startswith("spin")]
    assert max(map(abs, spins_after)) < 0.015


def test_a_two_wheel_car_is_calibrated_to_its_geometric_track(tmp_path):
    """Two wheels 0.14 m apart and no skid: the effective track is the geometric one."""
    fixtures = Path(__file__).parent / "fixtures"
    model = load_model(fixtures / "meshbot_description" / "urdf" / "meshbot.urdf",
                       package_path=[fixtures])
    assert model.track_width_m == pytest.approx(0.14)
    result = calibrate(model, load_controller_config(), SHORT, "spin")
    assert result.base_width_m == pytest.approx(0.14, rel=0.02)
    assert result.ticks_meter == pytest.approx(4100, rel=0.02)


def test_calibration_recovers_a_known_track_and_true_ticks_per_metre(shipped_model,
                                                                     shipped_config):
    """The plant's track is 1.15 times the model's and its encoders count 1.1 times the YAML's
    ticks_meter: the YAML should say 0.329 * 1.15 m and 4100 * 1.1 ticks/m."""
    plant = Variation(track=1.15, left_encoder_scale=1.1, right_encoder_scale=1.1)
    for fit_name in ("spin", "umbmark"):
        result = calibrate(shipped_model, shipped_config, SHORT, fit_name, variation=plant)
        assert result.base_width_m == pytest.approx(EFFECTIVE_TRACK_M * 1.15, rel=0.05)
        assert result.ticks_meter == pytest.approx(4510, rel=0.05)
        straight_after = RunError.of(result.after[0]).relative
        assert abs(straight_after) < 0.01 < abs(RunError.of(result.before[0]).relative)


def test_calibration_tells_unequal_wheels(shipped_model, shipped_config):
    plant = Variation(left_encoder_scale=1.0, right_encoder_scale=1.04)
    result = calibrate(shipped_model, shipped_config, SHORT, "spin", variation=plant)
    assert result.estimate.diameter_ratio == pytest.approx(1 / 1.04, rel=0.01)


def test_integrate_reproduces_the_drivers_odometry_and_the_fit_inverts_it():
    rng = np.random.default_rng(0)
    steps = np.cumsum(np.c_[rng.integers(0, 60, 300), rng.integers(0, 60, 300)], axis=0)
    ticks = np.vstack([[0, 0], steps]).astype(float)
    x, y, theta = integrate(ticks, 4100, 0.26)
    # by hand, with upstream's loop
    px = py = th = 0.0
    for (l0, r0), (l1, r1) in zip(ticks[:-1], ticks[1:], strict=True):
        dl, dr = (l1 - l0) / 4100, (r1 - r0) / 4100
        d, dth = (dl + dr) / 2, (dr - dl) / 0.26
        px += math.cos(th) * math.cos(dth) * d + math.sin(th) * math.sin(dth) * d
        py += math.sin(th) * math.cos(dth) * d - math.cos(th) * math.sin(dth) * d
        th += dth
    assert (x, y, theta) == pytest.approx((px, py, th), abs=1e-9)
    # a robot whose true track is 0.3 and whose right wheel goes 2 % further: fitted back
    runs = []
    for i, sign in enumerate((1, -1, 0)):
        t = ticks.copy()
        if sign:  # spins: wheels opposite
            t[:, 0] *= -sign
            t[:, 1] *= sign
        else:
            t[:, 1] = t[:, 0]  # straight
        end = integrate(t, 4100, 0.3, 1.0, 1.02)
        runs.append(Run(["spin ccw", "spin cw", "straight"][i], t, end, (0, 0, 0)))
    estimate = fit(runs, 4100, 0.26)
    assert estimate.base_width_m == pytest.approx(0.3, rel=1e-6)
    assert estimate.diameter_ratio == pytest.approx(1.02, rel=1e-6)
    with pytest.raises(CalibrationError, match="do not determine"):
        fit(runs[:2], 4100, 0.26)  # spins alone cannot tell the scale


def test_the_calibrated_yaml_keeps_layout_and_comments(shipped_config):
    text = Path(default_config_path()).read_text(encoding="utf-8")
    out = calibrated_text(text, shipped_config, 0.32917, 4099.64, "calibrated\n  line two")
    assert out.startswith("# calibrated\n#   line two\n# ArbotiX ROS driver configuration")
    old_lines, new_lines = text.splitlines(), out.splitlines()[2:]
    changed = [(a, b) for a, b in zip(old_lines, new_lines, strict=True) if a != b]
    assert changed == [("    base_width: 0.26", "    base_width: 0.3292"),
                       ("    ticks_meter: 4100", "    ticks_meter: 4099.6")]
    config = parse_controller_config(yaml.safe_load(out), "x")
    assert (config.base_width_m, config.ticks_meter) == (0.3292, 4099.6)


def test_a_flow_style_yaml_with_quoted_values_is_edited_in_place(tmp_path):
    path = tmp_path / "flow.yaml"
    path.write_text("port: /dev/ttyUSB0  # the board\ncontrollers: {base: {type: "
                    "diff_controller, ticks_meter: '4100', base_width: 0.26, Kp: 12}}\n")
    config = load_controller_config(path)
    out = calibrated_text(path.read_text(), config, 0.33, 4500, "note")
    assert out == ("# note\nport: /dev/ttyUSB0  # the board\ncontrollers: {base: {type: "
                   "diff_controller, ticks_meter: 4500, base_width: 0.3300, Kp: 12}}\n")


# -- the command line --------------------------------------------------------------------------
def test_cli_writes_the_calibrated_yaml_and_prints_before_and_after(tmp_path, capsys):
    source = _mis_set_yaml(tmp_path, ticks_meter="3700")
    out = tmp_path / "calibrated.yaml"
    code = cli.main(["--controller-config", str(source), "--randomize",
                     "{left_encoder_scale: 1.108, right_encoder_scale: 1.108}",
                     "--side", "0.5", "--output", str(out), "--json", str(tmp_path / "c.json")])
    assert code == 0
    printed = capsys.readouterr().out
    assert "UMBmark E_max,syst" in printed and f"wrote {out}" in printed
    config = load_controller_config(out)
    assert config.ticks_meter == pytest.approx(3700 * 1.108, rel=0.01)  # the true 4100
    assert config.base_width_m == pytest.approx(EFFECTIVE_TRACK_M, rel=0.05)
    assert out.read_text().startswith("# Calibrated by smartcar-calibrate (fit: spin)")


@pytest.mark.parametrize("argv, message", [
    (["--model", "nowhere.urdf"], "nowhere.urdf"),
    (["--controller-config", "nowhere.yaml"], "nowhere.yaml: controller config file not found"),
    (["--randomize", "{track: 3}"], "randomize: track: expected [low, high]"),
    (["--randomize", "{trak: 1.1}"], "unknown factor 'trak'"),
    (["--side", "-1"], "expected a positive number, got '-1'"),
    (["--max-substep-s", "0.5"], "--max-substep-s must be a number of seconds"),
    (["--output", "/nonexistent_folder/x.yaml"], "the folder /nonexistent_folder does not"),
    (["--wheels", "{left: [nope], right: [nope2]}"], "nope"),
])
def test_cli_bad_input_is_one_line_and_exit_code_2(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_info:
        cli.main(argv)
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("smartcar-calibrate: error: ") and message in err, err


@pytest.mark.parametrize("argv, named", [
    (["--bag", "robot_missing.bag", "--keep", "not_a_key", "--truth-topic", "/mocap"],
     "--bag, --truth-topic, --keep"),
    (["--start", "planar_pybullet"], "--start"),
    (["--cmd-topic", "/cmd_vel"], "--cmd-topic"),  # the default value, given: refused too
    (["--odom-topic", "/odom", "--fit", "umbmark"], "--odom-topic"),
    (["--generations", "3"], "--generations"),
])
def test_cli_refuses_the_planar_flags_without_fit_planar(argv, named, tmp_path, capsys):
    """They would be ignored, and the spin fit's YAML would replace the planar parameter file
    the user meant to write: one line, exit 2, the output left as it was."""
    out = tmp_path / "mine.yaml"
    out.write_text("planar: {}\n")
    with pytest.raises(SystemExit) as exit_info:
        cli.main([*argv, "-o", str(out)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (f"smartcar-calibrate: error: {named}: only with --fit planar (the "
                       "planar engine's parameters); the other fits ignore them"), err
    assert out.read_text() == "planar: {}\n"


def test_cli_a_car_that_cannot_move_is_reported(tmp_path, capsys):
    text = Path(default_config_path()).read_text(encoding="utf-8")
    path = tmp_path / "stuck.yaml"
    path.write_text(text.replace("    accel_limit: 1.0\n", "    accel_limit: 0.001\n"))
    with pytest.warns(UserWarning, match="can never move"), pytest.raises(SystemExit) as err:
        cli.main(["--controller-config", str(path)])
    assert err.value.code == 2
    assert "calibration failed: the car did not move as commanded" in capsys.readouterr().err


def test_smartcar_calibrate_needs_no_train_extra(tmp_path):
    """Core dependencies only: the training stack is made unimportable in a subprocess."""
    blocked = ("torch", "stable_baselines3", "tensorboard", "pandas", "matplotlib", "tqdm",
               "rich", "imageio_ffmpeg")
    code = textwrap.dedent(f"""
        import sys
        class Blocker:
            def find_spec(self, name, path=None, target=None):
                if name.partition(".")[0] in {blocked!r}:
                    raise ModuleNotFoundError(name)
        sys.meta_path.insert(0, Blocker())
        from smartcar_gym.calibration.cli import main
        print("EXIT", main(["--side", "0.5", "--output", {str(tmp_path / "c.yaml")!r}]))
    """)
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            timeout=300, check=False)
    assert result.returncode == 0, result.stderr
    assert "EXIT 0" in result.stdout and (tmp_path / "c.yaml").is_file()
