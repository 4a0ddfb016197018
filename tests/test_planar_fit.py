"""Identifying the planar engine (``calibration/planar_fit.py``, ``smartcar-calibrate --fit
planar``): known parameters recovered, batched replays equal to single ones, one-line errors."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from smartcar_gym.calibration import planar_fit
from smartcar_gym.calibration.cli import main
from smartcar_gym.calibration.planar_fit import FitError, check_excitation, fit
from smartcar_gym.calibration.planar_replay import FleetReplay
from smartcar_gym.calibration.recording import Recording, record, replay
from smartcar_gym.sim.planar.params import PlanarParams, load

TRUE = PlanarParams(friction_scale=0.8, lateral_friction_ratio=1.1, slip_speed=0.01,
                    rolling_resistance=0.02, gearbox_friction_scale=1.2, load_shift_x=0.008,
                    spin_reaction=0.5)


@pytest.fixture(scope="module")
def planar_drives(shipped_model, shipped_config) -> list[Recording]:
    """The fit's own drives on a planar car with known parameters (``TRUE``)."""
    return record(shipped_model, shipped_config, "planar", planar_params=TRUE)


def test_a_batched_replay_is_the_single_replay_bit_for_bit(shipped_model, shipped_config,
                                                             planar_drives) -> None:
    fleet = FleetReplay(shipped_model, shipped_config, planar_drives[:3])
    try:
        out = fleet.run([TRUE, PlanarParams()])
    finally:
        fleet.close()
    for c, params in enumerate((TRUE, PlanarParams())):
        for r, (truth, odom) in zip(planar_drives[:3], out[c], strict=True):
            single = replay(shipped_model, shipped_config, "planar", r.commands, r.truth[0],
                            planar_params=params)
            assert np.array_equal(single[1], odom)
            assert np.array_equal(single[0][:, :2], truth[:, :2])
            assert np.allclose(single[0][:, 2], truth[:, 2], rtol=0, atol=1e-12)
    # the true parameters retrace the recordings exactly
    assert np.array_equal(out[0][0][0][:, :2], planar_drives[0].truth[:, :2])


def test_the_fit_recovers_known_parameters(shipped_model, shipped_config, planar_drives):
    """The fit's drives on a planar car with ``TRUE`` give back its parameters. The spin
    reaction and the load shift both move load between the axles and trade against each other
    on this soft-tyred car (slip speed 1 cm/s): the search settles at 0.77 and 5 mm."""
    result = fit(shipped_model, shipped_config, planar_drives, generations=20)
    p = result.params
    assert p.friction_scale == pytest.approx(TRUE.friction_scale, rel=0.08)
    assert p.lateral_friction_ratio == pytest.approx(TRUE.lateral_friction_ratio, rel=0.04)
    assert p.gearbox_friction_scale == pytest.approx(TRUE.gearbox_friction_scale, rel=0.25)
    assert p.load_shift_x == pytest.approx(TRUE.load_shift_x, abs=0.003)
    assert p.spin_reaction == pytest.approx(TRUE.spin_reaction, abs=0.3)
    assert result.rms < 0.15
    assert result.rms < 0.5 * np.sqrt(np.mean(np.square(list(result.before.values()))))
    assert result.free == planar_fit.FREE


def test_kept_parameters_stay_and_unknown_ones_are_named(shipped_model, shipped_config,
                                                          planar_drives):
    keep = [k for k in planar_fit.FREE if k != "friction_scale"]
    start = dataclasses.replace(TRUE, friction_scale=1.0)
    result = fit(shipped_model, shipped_config, planar_drives, start=start, keep=keep,
                 generations=4)
    for key in keep:
        assert getattr(result.params, key) == getattr(TRUE, key)
    assert result.params.friction_scale == pytest.approx(0.8, rel=0.05)
    with pytest.raises(FitError, match="--keep slip: not a planar parameter"):
        fit(shipped_model, shipped_config, planar_drives, keep=["slip"])


def test_too_little_excitation_names_the_missing_maneuver(planar_drives) -> None:
    straight = [r for r in planar_drives if r.name.startswith("straight")]
    with pytest.raises(FitError, match="too little excitation.* of spin in place") as caught:
        check_excitation(straight, planar_fit.FREE)
    assert "--keep friction_scale,lateral_friction_ratio" in str(caught.value)
    seconds = check_excitation(planar_drives, planar_fit.FREE)
    assert seconds["spin in place"] >= 9.0 and seconds["stop from speed"] > 0
    assert seconds["turning in reverse"] >= 5.0
    assert seconds["reversal out of a turn"] >= planar_fit.MIN_REVERSAL_S
    forward = [r for r in planar_drives
               if not r.name.startswith(("arc -", "random", "reversal"))]
    with pytest.raises(FitError, match="of turning in reverse .*for load_shift_x; record it, "
                                       "or keep it with --keep load_shift_x"):
        check_excitation(forward, planar_fit.FREE)
    with pytest.raises(FitError, match="of reversal out of a turn .*for spin_reaction; record "
                                       "it, or keep it with --keep spin_reaction"):
        check_excitation(forward, [k for k in planar_fit.FREE if k != "load_shift_x"])
    check_excitation(forward, [k for k in planar_fit.FREE
                               if k not in ("load_shift_x", "spin_reaction")])
    # a reversal is a command against the motion: the reverse arcs from rest are not one
    reverse_arcs = [r for r in planar_drives if r.name.startswith("arc -")]
    assert check_excitation(reverse_arcs, [])["reversal out of a turn"] == 0.0


def test_a_fit_that_cannot_converge_gives_its_residual(shipped_model, shipped_config,
                                                       planar_drives):
    """Recordings whose ground truth turns the other way than the odometry: no parameters
    explain them."""
    mirrored = [dataclasses.replace(r, truth=r.truth * np.array([1.0, -1.0, -1.0]))
                for r in planar_drives]
    with pytest.raises(FitError, match=r"did not converge: RMS scaled residual \d+\.\d\d"):
        fit(shipped_model, shipped_config, mirrored, generations=2)


def test_the_command_line_writes_a_parameter_file(tmp_path, capsys, planar_drives) -> None:
    start = tmp_path / "true.yaml"
    from smartcar_gym.sim.planar.params import dump

    start.write_text(dump(TRUE))
    out = tmp_path / "fit.yaml"
    code = main(["--fit", "planar", "--engine", "planar", "--start", str(start),
                 "--keep", ",".join(k for k in planar_fit.FREE if k != "slip_speed"),
                 "--generations", "3", "-o", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "residual (RMS, scaled)" in text and "spin 1 rad/s" in text and "wrote" in text
    fitted = load(out)
    assert fitted.friction_scale == TRUE.friction_scale
    assert fitted.slip_speed == pytest.approx(TRUE.slip_speed, rel=0.3)
    assert "fit:" in out.read_text()


@pytest.mark.parametrize("argv, message", [
    (["--fit", "planar", "--engine", "planar"], "needs --start"),
    (["--fit", "planar", "--keep", "nonsense"], "--keep nonsense: not a planar parameter"),
    (["--fit", "planar", "--bag", "missing.bag"], "missing.bag"),
    (["--fit", "planar", "--start", "nothere.yaml"], "nothere.yaml: cannot read"),
])
def test_the_command_line_refuses_bad_input_in_one_line(argv, message, capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert message in err


AXLEBOT = ["--model", "tests/fixtures/axlebot_description/urdf/axlebot.urdf.xacro",
           "--controller-config", "tests/fixtures/axlebot_description/config/axlebot_arbotix.yaml"]


def test_a_robot_balanced_on_its_axle_is_fitted_inside_its_contacts(tmp_path, capsys) -> None:
    """The axlebot (centre of mass 1.4 mm behind its axle, a rear caster): the fit starts from
    neutral values, not the smartcar's fit, and searches the load shift only where its
    contacts carry it (the caster's load never negative); the smartcar's fit as ``--start``
    is refused in one line with the range."""
    out = tmp_path / "axlebot.yaml"
    assert main(["--fit", "planar", "--engine", "pybullet", *AXLEBOT, "--generations", "2",
                 "-o", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    assert -0.0737 <= load(out).load_shift_x <= 0.00137
    with pytest.raises(SystemExit) as stop:
        main(["--fit", "planar", "--engine", "pybullet", *AXLEBOT, "--start", "pybullet",
              "--generations", "2"])
    assert stop.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "planar.load_shift_x 0.00453577 m" in err and "contacts allow [-0.0736" in err


def test_the_drives_honour_the_wheel_contact_and_the_substep(shipped_model, shipped_config):
    """``record``'s ``wheel_contact`` and ``max_substep_s`` reach the engine: the URDF's
    cylinders and a shorter substep drive differently from the default spheres at 10 ms."""
    from smartcar_gym.calibration.maneuvers import hold

    drives = {"arc": hold((0.3, 1.0), 1.0, shipped_config.rate_hz)}
    runs = [record(shipped_model, shipped_config, "pybullet", drives, **options)[0].truth
            for options in ({}, {"wheel_contact": "urdf"}, {"max_substep_s": 0.002},
                            {"max_substep_s": 0.01})]
    assert not np.array_equal(runs[0], runs[1]) and not np.array_equal(runs[0], runs[2])
    assert np.array_equal(runs[0], runs[3])  # 10 ms: pybullet's default


def test_the_command_line_passes_its_drive_options_to_the_recordings(monkeypatch, capsys):
    from smartcar_gym.calibration import planar_cli

    seen = {}

    def recorded(model, config, engine, **options):
        seen.update(options, engine=engine)
        raise FitError("recorded")

    monkeypatch.setattr(planar_cli, "record", recorded)
    with pytest.raises(SystemExit):
        main(["--fit", "planar", "--engine", "pybullet", "--wheel-contact", "urdf",
              "--max-substep-s", "0.005"])
    assert seen == {"engine": "pybullet", "wheel_contact": "urdf", "max_substep_s": 0.005}
    assert "planar fit failed: recorded" in capsys.readouterr().err


@pytest.mark.parametrize("argv, message", [
    (["--generations", "-3"], "argument --generations: expected a positive integer, got '-3'"),
    (["--generations", "0"], "argument --generations: expected a positive integer, got '0'"),
    (["--bag", "robot.bag", "--engine", "mujoco"], "--engine mujoco does not apply with --bag"),
    (["--bag", "robot.bag", "--wheel-contact", "urdf"],
     "--wheel-contact urdf does not apply with --bag"),
    (["--bag", "robot.bag", "--max-substep-s", "0.002"],
     "--max-substep-s 0.002 does not apply with --bag"),
    (["--bag", "robot.bag", "--odom-topic", ""], "--odom-topic '': expected a topic name, "
                                                 "e.g. /odom"),
    (["--bag", "robot.bag", "--truth-topic", " "], "--truth-topic ' ': expected a topic name"),
])
def test_flags_the_planar_fit_cannot_honour_are_refused_in_one_line(argv, message, capsys):
    with pytest.raises(SystemExit) as stop:
        main(["--fit", "planar", *argv])
    assert stop.value.code == 2
    assert message in capsys.readouterr().err.strip().splitlines()[-1]
