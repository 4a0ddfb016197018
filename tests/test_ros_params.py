"""The bringup node's configuration from ROS parameters, its clock and its command checks (no ROS).

``controller_config`` gets the node's private namespace as ``rospy.get_param("~")`` returns
it: the tutorial's launch file loads ``smartcar_arbotix.yaml`` there.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

from smartcar_gym.controller import (
    ControllerConfigError,
    default_config_path,
    load_controller_config,
)
from smartcar_gym.ros.bringup import CommandInbox, twist_problem
from smartcar_gym.ros.params import controller_config, describe
from smartcar_gym.ros.timing import MAX_CATCH_UP_S, Pacer, Schedule, Stream, period_ns

SHIPPED = yaml.safe_load(Path(default_config_path()).read_text())


def _without_source(config):
    return dataclasses.replace(config, source="-")


def test_parameters_from_the_server_give_the_files_config():
    config, source = controller_config(SHIPPED, "/arbotix", fallback="/nonexistent.yaml")
    assert source == "the ROS parameter server /arbotix"
    assert _without_source(config) == _without_source(load_controller_config())


def test_server_parameters_are_read_as_arbotix_driver_reads_them():
    """Keys that are not on the server take upstream's defaults, not the file's."""
    params = {"controllers": {"base": {"type": "diff_controller", "ticks_meter": 4100,
                                       "base_width": 0.26}}}
    config, _ = controller_config(params, "/arbotix")
    assert (config.rate_hz, config.kp, config.read_rate_hz, config.accel_limit) == (
        10.0, 5, 10.0, 0.1)  # upstream's, where the shipped file says 10, 12, 20, 1.0
    assert config.name == "base"


def test_without_controllers_on_the_server_the_file_is_read():
    config, source = controller_config({}, "/arbotix")
    assert source == default_config_path()
    assert _without_source(config) == _without_source(load_controller_config())
    config, source = controller_config(None, "/arbotix")
    assert source == default_config_path()


def test_private_parameters_override_the_files_top_level_keys(tmp_path):
    path = tmp_path / "arbotix.yaml"
    path.write_text(yaml.safe_dump(SHIPPED))
    config, source = controller_config({"sim": True, "read_rate": 50}, "/arbotix", path)
    assert config.kinematic is True and config.read_rate_hz == 50.0
    assert config.ticks_meter == 4100  # the rest is the file's
    assert source == f"{path} with /arbotix parameters read_rate, sim"


def test_a_bad_server_configuration_names_the_server_and_key():
    params = {"controllers": {"base_controller": {"type": "diff_controller",
                                                  "base_frame_id": "base_link"}}}
    # what the tutorial's smartcar_arbotix.yaml leaves on the server: rosparam refuses the
    # null of its 'base_ 0.26' and uploads the keys before it
    with pytest.raises(ControllerConfigError, match=r"^ROS parameter server /arbotix: "
                       r"controllers.base_controller: required key 'ticks_meter' is missing"):
        controller_config(params, "/arbotix")


def test_a_bad_fallback_file_is_named(tmp_path):
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    with pytest.raises(ControllerConfigError, match="empty.yaml: expected a mapping of driver "
                                                    "parameters, got an empty file"):
        controller_config({}, "/arbotix", empty)
    with pytest.raises(ControllerConfigError, match="controller config file not found"):
        controller_config({}, "/arbotix", tmp_path / "missing.yaml")


def test_describe_names_the_values_that_shape_the_robot():
    assert describe(load_controller_config()) == (
        "base_controller: rate 10 Hz, timeout 1 s, ticks_meter 4100, base_width 0.26 m, "
        "Kp/Kd/Ki/Ko 12/12/0/50, accel_limit 1, frames odom -> base_link, read_rate 20 Hz, "
        "sim False")


# -- time ---------------------------------------------------------------------------------------
def test_schedule_gives_each_streams_instants_in_integer_ns():
    schedule = Schedule([Stream("odom", period_ns(10)), Stream("joints", period_ns(20)),
                         Stream("tick", period_ns(100))])
    seen = []
    for _ in range(12):
        now = schedule.next_ns()
        seen.append((now, schedule.due(now)))
    assert seen[:5] == [(10_000_000, ["tick"]), (20_000_000, ["tick"]), (30_000_000, ["tick"]),
                        (40_000_000, ["tick"]), (50_000_000, ["joints", "tick"])]
    assert seen[9] == (100_000_000, ["odom", "joints", "tick"])
    assert period_ns(15) == 66_666_667
    with pytest.raises(ValueError, match="the period must be positive"):
        Stream("x", 0)


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0
        self.slept = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.slept.append(seconds)
        self.now += seconds


def test_pacer_holds_simulated_time_to_the_wall_clock_times_speed():
    clock = FakeClock()
    pacer = Pacer(4.0, clock, clock.sleep)
    pacer.start(0)
    assert pacer.wait(400_000_000) == 0.0  # 0.4 s simulated = 0.1 s of wall clock at 4x
    assert clock.slept == [pytest.approx(0.1)]
    clock.now += 0.15  # 0.8 s simulated is due at +0.2 s: 50 ms late, caught up, no sleep
    assert pacer.wait(800_000_000) == pytest.approx(0.05)
    assert len(clock.slept) == 1 and pacer.falls == 0


def test_pacer_falls_behind_instead_of_bursting_after_a_long_stall():
    clock = FakeClock()
    pacer = Pacer(1.0, clock, clock.sleep)
    pacer.start(0)
    clock.now += 2.0  # the process stalled for 2 s
    assert pacer.wait(100_000_000) == pytest.approx(1.9)
    assert pacer.falls == 1 and pacer.behind_s == pytest.approx(1.9)
    assert pacer.wait(200_000_000) == 0.0  # restarted from the present: on time again
    assert clock.slept == [pytest.approx(0.1)]
    assert MAX_CATCH_UP_S < 1.9
    with pytest.raises(ValueError, match="speed must be a positive number"):
        Pacer(0.0)


# -- commands -----------------------------------------------------------------------------------
def test_twists_the_board_cannot_hold_are_refused():
    config = load_controller_config()
    assert twist_problem(0.5, 2.0, config) is None
    problem = twist_problem(300.0, 0.0, config)
    assert problem == ("cmd_vel (300 m/s, 0 rad/s) asks a wheel for 300 m/s; with ticks_meter "
                       "4100 the board's 16-bit target holds at most 239.759 m/s")


def test_command_inbox_hands_over_the_latest_twist_once():
    inbox = CommandInbox()
    assert inbox.take() is None
    inbox.put(0.1, 0.0)
    inbox.put(0.2, 0.5)
    assert inbox.take() == (0.2, 0.5) and inbox.take() is None
