"""ArbotiX controller YAML: upstream defaults, required keys, the seed's typo, bad values."""

from __future__ import annotations

import re
import textwrap
import warnings
from pathlib import Path

import pytest
import yaml

from smartcar_gym.controller import (
    ArbotixConfig,
    ControllerConfigError,
    MotorConfig,
    default_config_path,
    load_controller_config,
    parse_controller_config,
)

# The tutorial's file, verbatim (typo included); written to tmp_path by the tests.
SEED_YAML = textwrap.dedent(
    """\
    port: /dev/ttyUSB0
    baud: 115200
    rate: 20
    sync_write: True
    sync_read: True
    read_rate: 20
    write_rate: 20

    controllers: {
       #  Pololu motors: 1856 cpr = 0.3888105m travel = 4773 ticks per meter (empirical: 4100)
       base_controller: {type: diff_controller, base_frame_id: base_link, base_ 0.26, ticks_meter: 4100, Kp: 12, Kd: 12, Ki: 0, Ko: 50, accel_limit: 1.0 }
    }
    """  # noqa: E501
)


def minimal(**controller) -> dict:
    params = {"type": "diff_controller", "ticks_meter": 4100, "base_width": 0.26}
    params.update(controller)
    return {"controllers": {"base_controller": params}}


TWO = {"a": minimal()["controllers"]["base_controller"]}


def parse(data: dict) -> ArbotixConfig:
    return parse_controller_config(data, "test.yaml")


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "smartcar_arbotix.yaml"
    path.write_text(text)
    return path


def test_shipped_config_is_the_seed_with_base_width_fixed():
    config = load_controller_config()
    assert config.source == default_config_path()
    assert Path(config.source).name == "smartcar_arbotix.yaml"
    assert (config.ticks_meter, config.base_width_m) == (4100.0, 0.26)
    assert config.gains == (12, 12, 0, 50)
    assert config.accel_limit == 1.0
    assert config.max_accel == 410  # int(1.0 * 4100 / 10)
    assert (config.rate_hz, config.timeout_s) == (10.0, 1.0)  # not set: upstream defaults
    assert (config.base_frame_id, config.odom_frame_id) == ("base_link", "odom")
    assert (config.driver_rate_hz, config.read_rate_hz, config.write_rate_hz) == (20, 20, 20)
    assert config.kinematic is False  # the YAML's `sim` key
    assert config.name == "base_controller"
    assert config.motor == MotorConfig(0.34, 33.5, "coast", 1.8e-3, 0.03)
    assert (config.encoder_left, config.encoder_right) == ("auto", "auto")
    assert config.frame_ms == 33 and config.pwm_zero == "coast"


def test_shipped_config_differs_from_the_seed_only_by_base_width_and_our_section(tmp_path):
    seed = yaml.safe_load(SEED_YAML)
    shipped = yaml.safe_load(Path(default_config_path()).read_text())
    ours = shipped.pop("smartcar_gym")
    assert set(ours) == {"motor", "encoder", "board"}
    seed_controller = seed["controllers"]["base_controller"]
    assert seed_controller.pop("base_ 0.26") is None
    seed_controller["base_width"] = 0.26
    assert shipped == seed


def test_upstream_defaults():
    config = parse(minimal())
    assert (config.rate_hz, config.timeout_s, config.accel_limit) == (10.0, 1.0, 0.1)
    assert config.gains == (5, 1, 0, 50)
    assert (config.base_frame_id, config.odom_frame_id) == ("base_link", "odom")
    assert config.max_accel == 41  # int(0.1 * 4100 / 10)
    assert (config.driver_rate_hz, config.read_rate_hz, config.write_rate_hz) == (100, 10, 10)
    assert config.kinematic is False  # the YAML's `sim` key
    assert config.source == "test.yaml"


def test_max_accel_truncates():
    assert parse(minimal(accel_limit=0.05)).max_accel == 20  # int(20.5)
    assert parse(minimal(accel_limit=1.0, rate=20)).max_accel == 205


def test_seed_typo_names_file_key_and_fix(tmp_path):
    path = write(tmp_path, SEED_YAML)
    with pytest.raises(ControllerConfigError) as err:
        load_controller_config(path)
    message = str(err.value)
    assert str(path) in message
    assert "'base_ 0.26'" in message
    assert "`base_width: 0.26`" in message
    assert "controllers.base_controller" in message


def test_missing_required_key_without_lookalike():
    with pytest.raises(ControllerConfigError, match=r"required key 'ticks_meter' is missing\b"):
        parse({"controllers": {"b": {"type": "diff_controller", "base_width": 0.26}}})


@pytest.mark.parametrize(
    ("bad_key", "value", "required", "suggestion"),
    [
        ("base_widht", 0.26, "base_width", "`base_width: 0.26`"),
        ("basewidth", 0.3, "base_width", "`base_width: 0.3`"),
        ("ticks", 4100, "ticks_meter", "`ticks_meter: 4100`"),
        ("ticks_meter 4100", None, "ticks_meter", "`ticks_meter: 4100`"),
    ],
)
def test_lookalike_keys_are_pointed_at(bad_key, value, required, suggestion):
    params = {"type": "diff_controller", "ticks_meter": 4100, "base_width": 0.26}
    del params[required]
    params[bad_key] = value
    with pytest.raises(ControllerConfigError) as err:
        parse({"controllers": {"b": params}})
    assert repr(bad_key) in str(err.value)
    assert suggestion in str(err.value)


@pytest.mark.parametrize("key", ["Kp", "Kd", "Ki", "Ko"])
@pytest.mark.parametrize("value", [256, 1.5, -1, True, "12"])
def test_gains_must_be_bytes(key, value):
    with pytest.raises(ControllerConfigError, match=rf"controllers\.base_controller\.{key}:"):
        parse(minimal(**{key: value}))


def test_gain_bounds_are_inclusive_and_ko_must_divide():
    assert parse(minimal(Kp=0, Kd=255, Ki=255, Ko=255)).gains == (0, 255, 255, 255)
    with pytest.raises(ControllerConfigError, match=r"Ko: .*divides"):
        parse(minimal(Ko=0))


@pytest.mark.parametrize(
    ("data", "where"),
    [
        (minimal(ticks_meter=-4100), "ticks_meter"),
        (minimal(ticks_meter=0), "ticks_meter"),
        (minimal(base_width=0.0), "base_width"),
        (minimal(base_width="wide"), "base_width"),
        (minimal(ticks_meter="-4100"), "ticks_meter"),
        (minimal(rate=0), "base_controller.rate"),
        (minimal(timeout=-0.1), "timeout"),
        (minimal(accel_limit=-1.0), "accel_limit"),
        (minimal(accel_limit=float("nan")), "accel_limit"),
        (minimal(odom_frame_id=""), "odom_frame_id"),
        ({**minimal(), "rate": -20}, "test.yaml: rate"),
        ({**minimal(), "sim": "yes"}, "test.yaml: sim"),
    ],
)
def test_bad_values_name_their_key(data, where):
    with pytest.raises(ControllerConfigError, match=where):
        parse(data)


def test_required_keys_take_numeric_strings_as_upstream_float_does():
    # upstream: float(rospy.get_param('~controllers/<name>/ticks_meter')), same for base_width
    config = parse(minimal(ticks_meter="4100", base_width="0.26"))
    assert (config.ticks_meter, config.base_width_m) == (4100.0, 0.26)


def test_number_read_as_text_gets_a_yaml_hint():
    # YAML 1.1 (PyYAML, rosparam) reads 1e-3 as the string '1e-3'; upstream would fail later
    data = yaml.safe_load("controllers: {b: {type: diff_controller, ticks_meter: 4100, "
                          "base_width: 0.26, accel_limit: 1e-3}}")
    with pytest.raises(ControllerConfigError, match=r"accel_limit.*'1e-3'.*write 1\.0e-3"):
        parse(data)


def test_zero_timeout_and_zero_accel_limit_are_allowed():
    assert parse(minimal(timeout=0)).timeout_s == 0.0
    with pytest.warns(UserWarning, match="max_accel .* = 0"):
        assert parse(minimal(accel_limit=0)).max_accel == 0


def test_null_value_is_an_error():
    with pytest.raises(ControllerConfigError, match=r"base_controller\.Kp: has no value"):
        parse(minimal(Kp=None))


def test_unknown_controller_key_warns_with_suggestion():
    with pytest.warns(UserWarning, match=r"'timout' ignored \(did you mean 'timeout'\?\)"):
        config = parse(minimal(timout=2.0))
    assert config.timeout_s == 1.0


def test_unknown_type_names_it_and_the_supported_one():
    data = minimal()
    data["controllers"]["base_controller"]["type"] = "diff_controler"
    with pytest.raises(ControllerConfigError) as err:
        parse(data)
    assert "'diff_controler'" in str(err.value) and "'diff_controller'" in str(err.value)


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"port": "/dev/ttyUSB0"}, "no 'controllers' section"),
        ({"controllers": [1, 2]}, "must be a mapping"),
        ({"controllers": {"arm": {"type": "follow_controller"}}}, "no diff_controller"),
        ({"controllers": {"b": {"ticks_meter": 1}}}, "no 'type'"),
        ({"controllers": {"b": "diff_controller"}}, "expected a mapping"),
        ({"controllers": {"a": TWO["a"], "b": TWO["a"]}}, "more than one"),
        ([1, 2], "expected a mapping"),
    ],
)
@pytest.mark.filterwarnings("ignore:.*not emulated")
def test_controller_section_shape(data, match):
    with pytest.raises(ControllerConfigError, match=match):
        parse(data)


def test_other_upstream_controllers_are_ignored_with_a_warning():
    data = minimal()
    data["controllers"]["arm_controller"] = {"type": "follow_controller", "joints": ["a"]}
    with pytest.warns(UserWarning, match="follow_controller.*not emulated"):
        assert parse(data).name == "base_controller"


def test_driver_level_keys_are_tolerated():
    data = {**minimal(), "port": "/dev/ttyACM0", "baud": 57600, "sync_read": False,
            "sync_write": True, "timeout": 0.1, "rate": 20, "read_rate": 20, "write_rate": 20,
            "sim": False, "diagnostic_rate": 1.0, "joints": {}, "dynamixels": {}, "servos": {},
            "digital_servos": {}, "digital_sensors": {}, "analog_sensors": {}, "smartcar_gym": {}}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # none of arbotix_driver's keys is warned about
        assert parse(data).ticks_meter == 4100


@pytest.mark.parametrize(("key", "hint"), [
    ("rat", " (did you mean 'rate'?)"),
    ("ticks_meter", " (a diff_controller key: it belongs under controllers.base_controller)"),
    ("colour", ""),
])
def test_unknown_top_level_key_warns_like_unknown_controller_keys(key, hint):
    with pytest.warns(UserWarning) as caught:  # `rat: 5` used to pass without a word
        parse({**minimal(), key: 5})
    assert [str(w.message) for w in caught] == [
        f"test.yaml: unknown top-level key {key!r} ignored{hint}"]


BASE = ("rate: 20\ncontrollers:\n  base_controller:\n    type: diff_controller\n"
        "    ticks_meter: 4100\n    base_width: 0.26\n    Kp: 12\n")


def test_duplicate_key_names_the_key_and_both_lines(tmp_path):
    path = write(tmp_path, BASE + "    ticks_meter: 10\n")  # PyYAML keeps 10: the car stands
    with pytest.raises(ControllerConfigError) as err:
        load_controller_config(path)
    assert str(err.value) == (
        f"{path}:8: key 'ticks_meter' given twice in one mapping, on lines 5 and 8 "
        "(ticks_meter: 4100, then ticks_meter: 10); YAML would keep the last one without a "
        "word; expected each key once")


@pytest.mark.parametrize(("text", "match"), [
    ("rate: 10\n" + BASE, r":2: key 'rate' given twice in one mapping, on lines 1 and 2 "),
    (BASE + "smartcar_gym:\n  motor: {stall_torque: 0.3, stall_torque: 3}\n",
     r":9: key 'stall_torque' given twice in one mapping, on line 9 \(stall_torque: 0.3, then "
     r"stall_torque: 3\)"),
    (BASE + "smartcar_gym:\n  board: {}\n  board:\n    frame_ms: 20\n",
     r":10: key 'board' given twice .* \(board: a mapping, then board: a mapping\)"),
])
def test_duplicate_keys_at_any_depth(tmp_path, text, match):
    with pytest.raises(ControllerConfigError, match=match):
        load_controller_config(write(tmp_path, text))


def test_a_merge_key_may_be_overridden(tmp_path):
    config = load_controller_config(write(tmp_path, BASE + "    <<: {Kd: 3, Ki: 2}\n    Kd: 4\n"))
    assert (config.kp, config.kd, config.ki) == (12, 4, 2)


def test_ticks_meter_that_overflows_the_board_is_refused_naming_the_limit():
    with pytest.raises(ControllerConfigError) as err:
        parse(minimal(ticks_meter="1e12"))  # YAML 1.1 reads 1e12 as text; upstream float()s it
    assert str(err.value) == (
        "test.yaml: controllers.base_controller.ticks_meter: 1e+12 ticks/m overflows the emulated "
        "board's integers: a 1 m/s wheel target would be 3.33333e+10 ticks per 1/30 s frame, "
        "beyond the 16-bit int the board takes (32767), and its 32-bit encoder count would wrap "
        "after 2.15 mm of travel; expected at most 983010 (a 16-bit target up to 1 m/s)")
    assert parse(minimal(ticks_meter=983010)).max_target_speed_m_s == 1.0
    with pytest.raises(ControllerConfigError, match="expected at most 983010"):
        ArbotixConfig(ticks_meter=983011, base_width_m=0.26)


def test_max_target_speed_is_the_fastest_target_that_fits_int16():
    config = load_controller_config()
    assert config.max_target_speed_m_s == pytest.approx(239.7585, abs=1e-4)  # 32767*30/4100
    assert round(config.max_target_speed_m_s * config.ticks_meter / 30) == 2**15 - 1


def test_an_infinite_ramp_step_is_refused():
    with pytest.raises(ControllerConfigError, match=r"accel_limit: 1e\+308 makes the ramp step "
                                                    r"int\(accel_limit\*ticks_meter/rate\) "
                                                    "infinite"):
        parse(minimal(accel_limit=1e308))


def test_empty_path_directory_and_wrong_type(tmp_path):
    with pytest.raises(ControllerConfigError) as err:  # was ": controller config file not found"
        load_controller_config("")
    assert str(err.value) == ("controller config path is empty (''); expected the path of an "
                              "ArbotiX driver YAML file, or None for the shipped "
                              "smartcar_arbotix.yaml")
    write(tmp_path, SEED_YAML)
    with pytest.raises(ControllerConfigError) as err:  # was "cannot read: Is a directory"
        load_controller_config(tmp_path)
    assert str(err.value) == (f"{tmp_path}: is a directory; expected an ArbotiX driver YAML "
                              "file; it holds smartcar_arbotix.yaml")
    with pytest.raises(TypeError, match=r"^controller config path=5: expected the path \(str"):
        load_controller_config(5)


def test_yaml_syntax_error_names_file_and_line(tmp_path):
    text = "rate: 20\ncontrollers:\n  b: {type: diff_controller, ticks_meter: 4100\n  x: 1\n"
    path = write(tmp_path, text)  # the flow mapping on line 3 is never closed
    with pytest.raises(ControllerConfigError, match=rf"^{re.escape(str(path))}:4:4: YAML syntax"):
        load_controller_config(path)


def test_binary_file_is_named(tmp_path):
    path = tmp_path / "arbotix.yaml"
    path.write_bytes(b"\xff\xfe\x00rate: 10\n")
    with pytest.raises(ControllerConfigError, match=r"arbotix\.yaml: not UTF-8 text \(byte 0\)"):
        load_controller_config(path)


def test_missing_and_empty_files(tmp_path):
    with pytest.raises(ControllerConfigError, match="nope.yaml: controller config file not found"):
        load_controller_config(tmp_path / "nope.yaml")
    with pytest.raises(ControllerConfigError, match="is empty"):
        load_controller_config(write(tmp_path, "# nothing\n"))


def test_own_section_overrides():
    data = minimal()
    data["smartcar_gym"] = {
        "motor": {"stall_torque": 0.3, "no_load_speed": 20.0},
        "encoder": {"left": "left_back_wheel_joint"},
        "board": {"frame_ms": 20, "pwm_zero": "brake"},
    }
    config = parse(data)
    assert config.motor == MotorConfig(0.3, 20.0, "brake")
    assert config.pwm_zero == "brake"
    assert (config.encoder_left, config.encoder_right) == ("left_back_wheel_joint", "auto")
    assert config.frame_ms == 20


@pytest.mark.parametrize(
    ("own", "match"),
    [
        ({"motors": {}}, r"unknown key 'motors' \(did you mean 'motor'\?\)"),
        ({"motor": {"stall_torq": 0.2}}, r"motor: unknown key 'stall_torq'.*'stall_torque'"),
        ({"motor": {"stall_torque": -0.2}}, r"smartcar_gym\.motor\.stall_torque: must be > 0"),
        ({"motor": {"no_load_speed": 0}}, r"no_load_speed: must be > 0"),
        ({"board": {"frame_ms": 0}}, r"board\.frame_ms"),
        ({"board": {"frame_ms": 33.0}}, r"board\.frame_ms"),
        ({"board": {"pwm_zero": "float"}}, r"board\.pwm_zero: expected one of"),
        ({"encoder": {"left": 3}}, r"encoder\.left"),
        ({"encoder": "auto"}, r"smartcar_gym\.encoder: expected a mapping"),
        ("yes", r"smartcar_gym: expected a mapping"),
    ],
)
def test_own_section_errors(own, match):
    with pytest.raises(ControllerConfigError, match=match):
        parse({**minimal(), "smartcar_gym": own})


def test_direct_construction_is_validated():
    assert ArbotixConfig(ticks_meter=4100, base_width_m=0.26).max_accel == 41
    with pytest.raises(ControllerConfigError, match="ticks_meter"):
        ArbotixConfig(ticks_meter=-1, base_width_m=0.26)
    with pytest.raises(ControllerConfigError, match="Kp"):
        ArbotixConfig(ticks_meter=4100, base_width_m=0.26, kp=300)
    with pytest.raises(ControllerConfigError, match="pwm_zero"):
        MotorConfig(pwm_zero="float")
