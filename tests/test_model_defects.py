"""Defects of the tutorial's model (seed-style fixture): reported, strict, repaired."""

from __future__ import annotations

import math
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from smartcar_gym.model import ModelDefectWarning, ModelError, load_model
from smartcar_gym.model.defects import (
    DUPLICATED_ORIGIN,
    GEOMETRY_MISMATCH,
    IMPLAUSIBLE_INERTIA,
    NON_PHYSICAL_INERTIA,
    NON_POSITIVE_MASS,
    NOT_POSITIVE_DEFINITE,
)
from smartcar_gym.model.inertia import shape_inertia
from smartcar_gym.model.loader import inspect_model
from smartcar_gym.model.urdf import Geometry

SEEDLIKE = Path(__file__).parent / "fixtures" / "seedlike.urdf"
WHEELS = ["left_front_wheel", "right_front_wheel", "left_back_wheel", "right_back_wheel"]
CYLINDER = (0.1 * (3 * 0.025**2 + 0.02**2) / 12, 0.1 * (3 * 0.025**2 + 0.02**2) / 12,
            0.1 * 0.025**2 / 2)
BASE_BOX = ((0.16**2 + 0.05**2) / 12, (0.25**2 + 0.05**2) / 12, (0.25**2 + 0.16**2) / 12)


def load(path: Path = SEEDLIKE, **kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = load_model(path, **kwargs)
    return model, [str(w.message) for w in caught if w.category is ModelDefectWarning]


@pytest.fixture(scope="module")
def repaired():
    return load()


@pytest.fixture(scope="module")
def unrepaired():
    return load(repair=False)


def test_the_three_seed_defects_are_reported(unrepaired) -> None:
    model, _ = unrepaired
    kinds = {d.kind for d in model.defects}
    assert kinds == {DUPLICATED_ORIGIN, IMPLAUSIBLE_INERTIA, GEOMETRY_MISMATCH}
    assert all(d.severity == "warning" for d in model.defects)
    duplicated = [d.element for d in model.defects if d.kind == DUPLICATED_ORIGIN]
    assert duplicated == [f"{link}/{part}" for link in [*WHEELS, "head"]
                          for part in ("inertial", "collision")]
    implausible = [d.element for d in model.defects if d.kind == IMPLAUSIBLE_INERTIA]
    assert implausible == [f"{link}/inertia" for link in ["base_link", *WHEELS, "head"]]
    mismatch = [d for d in model.defects if d.kind == GEOMETRY_MISMATCH]
    assert [(d.element, d.message) for d in mismatch] == [(
        "head/collision", "collision geometry cylinder differs from visual geometry box; "
                          "expected the same shape")]


def test_defect_messages_carry_the_numbers(unrepaired) -> None:
    model, _ = unrepaired
    by_element = {(d.kind, d.element): d for d in model.defects}
    wheel = by_element[(DUPLICATED_ORIGIN, "left_front_wheel/collision")]
    assert wheel.message == (
        "origin xyz 0.08 0.08 0.025 rpy 0 1.57075 1.57075 repeats joint "
        "'left_front_wheel_joint' origin; the link frame is already there, so this puts it at "
        "0 0.105 -0.055 in 'base_link' instead of 0.08 0.08 0.025; expected xyz 0 0 0")
    head = by_element[(DUPLICATED_ORIGIN, "head/inertial")]
    assert "puts it at 0.16 0 0.16 in 'base_link' instead of 0.08 0 0.08" in head.message
    inertia = by_element[(IMPLAUSIBLE_INERTIA, "left_front_wheel/inertia")]
    assert inertia.message == (
        "principal moments 1 1 1 kg m^2, but a solid cylinder of 0.1 kg with size 0.025 0.02 m "
        "has 1.89583e-05 1.89583e-05 3.125e-05 (up to 5.27e+04x off, more than 10x)")
    assert str(inertia) == f"warning: implausible inertia: left_front_wheel/inertia: " \
                           f"{inertia.message}"


def test_without_repair_the_model_keeps_the_bugs(unrepaired) -> None:
    model, messages = unrepaired
    assert model.repairs == ()
    assert len(messages) == len(model.defects) == 17
    assert not any("repaired" in m for m in messages)
    collision = model.links["left_front_wheel"].collisions[0].origin
    assert collision.xyz == (0.08, 0.08, 0.025)
    assert model.links["left_front_wheel"].inertial.inertia[0][0] == 1.0
    assert model.wheel_radius_m == 0.025  # still drivable on paper


def test_strict_raises_listing_the_defects() -> None:
    with pytest.raises(ModelError) as info:
        load_model(SEEDLIKE, strict=True)
    message = str(info.value)
    assert message.startswith(f"{SEEDLIKE}: 17 model defect(s) (strict=True): warning: "
                              "implausible inertia: base_link/inertia: principal moments 1 1 1")
    assert "duplicated joint origin: head/collision" in message
    assert "geometry mismatch: head/collision" in message


def test_strict_passes_a_clean_model() -> None:
    assert load_model(strict=True).defects == ()


def test_repair_moves_duplicated_origins_to_the_link_frame(repaired) -> None:
    model, _ = repaired
    for link in WHEELS:
        assert model.links[link].collisions[0].origin.xyz == (0.0, 0.0, 0.0)
        assert model.links[link].collisions[0].origin.rpy == (0.0, 0.0, 0.0)  # rpy repeated too
        assert model.links[link].inertial.origin.xyz == (0.0, 0.0, 0.0)
        assert model.links[link].visuals[0].origin.xyz == (0.0, 0.0, 0.0)
    assert model.links["head"].collisions[0].origin.xyz == (0.0, 0.0, 0.0)
    assert model.links["base_link"].collisions[0].origin.xyz == (0.0, 0.0, 0.055)  # untouched
    assert model.joints["left_front_wheel_joint"].origin.xyz == (0.08, 0.08, 0.025)


def test_repair_replaces_implausible_inertias(repaired) -> None:
    model, _ = repaired
    for link in [*WHEELS, "head"]:  # the head's collision is (still) the seed's cylinder
        tensor = np.array(model.links[link].inertial.inertia)
        np.testing.assert_allclose(tensor, np.diag(CYLINDER), rtol=1e-9, atol=1e-15)
    base = np.array(model.links["base_link"].inertial.inertia)
    np.testing.assert_allclose(base, np.diag(BASE_BOX), rtol=1e-9)
    assert base[0, 0] == pytest.approx(0.00234167, rel=1e-5)


def test_repairs_are_listed_warned_and_in_the_urdf_text(repaired) -> None:
    model, messages = repaired
    assert len(model.repairs) == 16
    assert [r.kind for r in model.repairs] == [DUPLICATED_ORIGIN] * 10 + [IMPLAUSIBLE_INERTIA] * 6
    first = model.repairs[1]
    assert (first.element, first.message) == (
        "left_front_wheel/collision", "origin xyz 0.08 0.08 0.025 rpy 0 1.57075 1.57075 -> "
                                      "xyz 0 0 0 rpy 0 0 0 (it repeated joint "
                                      "'left_front_wheel_joint')")
    assert model.repairs[-1].message == (
        "ixx=1.0 iyy=1.0 izz=1.0 -> ixx=1.896e-05 iyy=1.896e-05 izz=3.125e-05 kg m^2 "
        "(solid cylinder 0.025 0.02 m, 0.1 kg)")
    assert len(messages) == 17  # one warning per defect, naming its repair
    assert sum("; repaired: " in m for m in messages) == 16
    assert messages[0].startswith("seedlike.urdf: warning: implausible inertia: base_link/")
    root = ET.fromstring(model.urdf)
    link = next(e for e in root.iter("link") if e.get("name") == "right_back_wheel")
    assert link.find("collision/origin").attrib == {"rpy": "0 0 0", "xyz": "0 0 0"}
    assert float(link.find("inertial/inertia").get("izz")) == pytest.approx(3.125e-05)


def test_repaired_model_has_no_defects_left_but_the_head_mismatch(repaired, tmp_path) -> None:
    model, _ = repaired
    path = model.write_urdf(tmp_path)
    again, _ = load(path)
    assert [(d.kind, d.element) for d in again.defects] == [(GEOMETRY_MISMATCH, "head/collision")]


def settle(model, tmp_path: Path, seconds: float = 2.0) -> float:
    """Up-axis z of base_link after dropping the model on a plane for ``seconds``."""
    from smartcar_gym.sim.pybullet.bullet import connect

    client = connect()
    try:
        client.setGravity(0, 0, -9.81)
        client.loadURDF("plane.urdf")
        body = client.loadURDF(str(model.write_urdf(tmp_path)), [0, 0, 0.001],
                               flags=client.URDF_USE_INERTIA_FROM_FILE)
        for _ in range(int(240 * seconds)):
            client.stepSimulation()
        return client.getMatrixFromQuaternion(client.getBasePositionAndOrientation(body)[1])[8]
    finally:
        client.disconnect()


def test_repair_is_what_keeps_the_car_on_its_wheels(repaired, unrepaired, tmp_path) -> None:
    assert settle(repaired[0], tmp_path / "fixed") > 0.999
    assert settle(unrepaired[0], tmp_path / "raw") < 0.98  # tilts on misplaced wheel shapes


def write_one_wheel_robot(tmp_path: Path, link_body: str) -> Path:
    wheels = "".join(
        f'  <link name="{side}"><collision><origin rpy="1.5707963267948966 0 0"/><geometry>'
        f'<cylinder radius="0.03" length="0.02"/></geometry></collision></link>\n'
        f'  <joint name="{side}_j" type="continuous"><parent link="base"/><child link="{side}"/>'
        f'<origin xyz="0 {y} 0"/><axis xyz="0 1 0"/></joint>\n'
        for side, y in (("l", 0.1), ("r", -0.1)))
    path = tmp_path / "robot.urdf"
    path.write_text(f'<robot name="r">\n  <link name="base"/>\n{wheels}'
                    f'  <link name="arm">{link_body}</link>\n'
                    '  <joint name="arm_j" type="fixed"><parent link="base"/><child link="arm"/>'
                    '<origin xyz="0 0.1 0"/></joint>\n</robot>\n')
    return path


def test_repair_keeps_an_rpy_that_does_not_repeat_the_joint_and_rotates_inertia(
        tmp_path: Path) -> None:
    body = ('<inertial><mass value="2"/><inertia ixx="5" ixy="0" ixz="0" iyy="5" iyz="0" '
            'izz="5"/></inertial><collision><origin xyz="0 0.1 0" rpy="1.5707963267948966 0 0"/>'
            '<geometry><cylinder radius="0.1" length="0.3"/></geometry></collision>')
    model, messages = load(write_one_wheel_robot(tmp_path, body))
    arm = model.links["arm"]
    assert arm.collisions[0].origin.xyz == (0.0, 0.0, 0.0)
    assert arm.collisions[0].origin.rpy == pytest.approx((math.pi / 2, 0, 0))
    side = 2 * (3 * 0.1**2 + 0.3**2) / 12
    np.testing.assert_allclose(np.array(arm.inertial.inertia),  # cylinder axis along link y
                               np.diag([side, 2 * 0.1**2 / 2, side]), atol=1e-12)
    assert [r.element for r in model.repairs] == ["arm/collision", "arm/inertia"]
    assert len(messages) == 2


NOT_REPAIRABLE = (" (not repairable: an inertia is computed only for a link with one box, "
                  "cylinder or sphere collision)")


@pytest.mark.parametrize(("inertial", "kind", "text"), [
    ('<mass value="0"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>',
     NON_POSITIVE_MASS, "mass 0 kg; expected > 0"),
    ('<mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>',
     NON_POSITIVE_MASS, "mass -1 kg; expected > 0"),
    ('<mass value="1"/><inertia ixx="1" ixy="2" ixz="0" iyy="1" iyz="0" izz="1"/>',
     NOT_POSITIVE_DEFINITE, "inertia principal moments -1 1 3 kg m^2; expected all > 0"),
    ('<mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="3"/>',
     NON_PHYSICAL_INERTIA, "inertia principal moments 1 1 3 kg m^2: 1 + 1 < 3, which no mass "
                           "distribution has; expected each moment at most the sum of the other "
                           "two"),
])
def test_error_severity_defects(tmp_path: Path, inertial: str, kind: str, text: str) -> None:
    path = write_one_wheel_robot(tmp_path, f'<inertial>{inertial}</inertial>')
    element = f"arm/{'inertial' if kind == NON_POSITIVE_MASS else 'inertia'}"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = inspect_model(path)
    assert [(d.kind, d.element, d.message, d.severity) for d in model.defects] == [
        (kind, element, text, "error")]
    assert model.errors == model.defects
    assert [str(w.message) for w in caught] == [f"robot.urdf: error: {kind}: {element}: {text}"]
    with pytest.raises(ModelError, match=f"1 model defect\\(s\\) \\(strict=True\\): error: {kind}"):
        load_model(path, strict=True)


@pytest.mark.parametrize(("inertial", "kind", "text"), [
    ('<mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/>',
     NON_POSITIVE_MASS, "mass -1 kg; expected > 0"),
    ('<mass value="1"/><inertia ixx="1" ixy="2" ixz="0" iyy="1" iyz="0" izz="1"/>',
     NOT_POSITIVE_DEFINITE, "inertia principal moments -1 1 3 kg m^2; expected all > 0"
     + NOT_REPAIRABLE),
    ('<mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="3"/>',
     NON_PHYSICAL_INERTIA, "inertia principal moments 1 1 3 kg m^2: 1 + 1 < 3, which no mass "
                           "distribution has; expected each moment at most the sum of the other "
                           "two" + NOT_REPAIRABLE),
])
def test_load_model_refuses_a_non_physical_model_naming_file_link_and_value(
        tmp_path: Path, inertial: str, kind: str, text: str) -> None:
    path = write_one_wheel_robot(tmp_path, f'<inertial>{inertial}</inertial>')
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == (f"{path}:7: non-physical model, cannot be simulated (1 error; "
                               f"`smartcar-model check` lists every defect): link 'arm': {kind}: "
                               f"{text}")
    assert (info.value.file, info.value.line) == (str(path), 7)


def test_a_non_physical_link_in_a_xacro_file_is_located_there(tmp_path: Path) -> None:
    path = write_one_wheel_robot(tmp_path, '<inertial><mass value="-0.5"/><inertia ixx="1" '
                                           'ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>')
    xacro_file = path.rename(tmp_path / "robot.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(xacro_file)
    assert (info.value.file, info.value.line) == (str(xacro_file), 7)
    assert "link 'arm': non-positive mass: mass -0.5 kg; expected > 0" in str(info.value)


def test_all_unrepaired_errors_are_listed_and_warnings_still_warned(tmp_path: Path) -> None:
    body = ('<inertial><mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" '
            'izz="1"/></inertial><collision><geometry><box size="0.1 0.1 0.1"/></geometry>'
            '</collision><visual><geometry><sphere radius="0.1"/></geometry></visual>')
    path = write_one_wheel_robot(tmp_path, body)
    text = path.read_text().replace('<link name="base"/>', '<link name="base"><inertial><mass '
                                    'value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" '
                                    'iyz="0" izz="-1"/></inertial></link>')
    path.write_text(text)
    with warnings.catch_warnings(record=True) as caught, pytest.raises(ModelError) as info:
        warnings.simplefilter("always")
        load_model(path, repair=False)
    message = str(info.value)
    assert message.startswith(f"{path}:2: non-physical model, cannot be simulated (2 errors;")
    assert "link 'base': non-positive-definite inertia: inertia principal moments -1 1 1" in message
    assert message.endswith("; link 'arm': non-positive mass: mass -1 kg; expected > 0")
    assert [str(w.message) for w in caught] == [  # the warning-level defect is still warned
        "robot.urdf: warning: geometry mismatch: arm/collision: collision geometry box differs "
        "from visual geometry sphere; expected the same shape"]


def test_non_positive_definite_inertia_is_repaired_when_the_shape_is_known(tmp_path) -> None:
    body = ('<inertial><mass value="1"/><inertia ixx="-1" ixy="0" ixz="0" iyy="1" iyz="0" '
            'izz="1"/></inertial><collision><geometry><sphere radius="0.1"/></geometry>'
            '</collision>')
    model, messages = load(write_one_wheel_robot(tmp_path, body))
    assert [(d.kind, d.severity) for d in model.defects] == [(NOT_POSITIVE_DEFINITE, "error")]
    assert [r.kind for r in model.repairs] == [NOT_POSITIVE_DEFINITE]
    assert model.errors == ()
    assert messages[0].endswith("; repaired: ixx=-1 iyy=1 izz=1 -> ixx=0.004 iyy=0.004 "
                                "izz=0.004 kg m^2 (solid sphere 0.1 m, 1 kg)")
    np.testing.assert_allclose(np.array(model.links["arm"].inertial.inertia),
                               np.eye(3) * 0.4 * 0.1**2, atol=1e-15)
    with pytest.raises(ModelError, match="repair=True replaces it with the inertia of its "
                                         "collision shape"):
        load_model(write_one_wheel_robot(tmp_path, body), repair=False)


def test_non_physical_inertia_is_repaired_when_the_shape_is_known(tmp_path) -> None:
    body = ('<inertial><mass value="1"/><inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" '
            'iyz="0" izz="0.003"/></inertial><collision><geometry><sphere radius="0.1"/>'
            '</geometry></collision>')
    model, _ = load(write_one_wheel_robot(tmp_path, body))
    assert [(d.kind, d.severity) for d in model.defects] == [(NON_PHYSICAL_INERTIA, "error")]
    assert [r.kind for r in model.repairs] == [NON_PHYSICAL_INERTIA] and model.errors == ()
    np.testing.assert_allclose(np.array(model.links["arm"].inertial.inertia),
                               np.eye(3) * 0.4 * 0.1**2, atol=1e-15)


@pytest.mark.parametrize(("izz", "refused"), [(2.0, False), (2.019, False), (2.03, True)])
def test_triangle_inequality_allows_one_percent_for_rounding(tmp_path, izz, refused) -> None:
    body = (f'<inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" '
            f'izz="{izz}"/></inertial>')  # a thin disc has izz = ixx + iyy exactly
    path = write_one_wheel_robot(tmp_path, body)
    if refused:
        with pytest.raises(ModelError, match="non-physical inertia"):
            load_model(path)
    else:
        assert load_model(path).defects == ()


I_SPHERE = 0.4 * 0.1**2  # solid sphere, 1 kg, r = 0.1 m


@pytest.mark.parametrize("moments", [(9, 9, 9), (1 / 9, 1 / 9, 1 / 9), (5, 5, 9)])
def test_plausible_inertia_within_ten_times_is_not_flagged(tmp_path: Path, moments) -> None:
    # (9, 1/9, 1) used to be here: within 10x, but 1/9 + 1 < 9 is no body's inertia (an error now)
    ixx, iyy, izz = (m * I_SPHERE for m in moments)
    body = (f'<inertial><mass value="1"/><inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" '
            f'iyz="0" izz="{izz}"/></inertial><collision><geometry><sphere radius="0.1"/>'
            '</geometry></collision>')
    model, messages = load(write_one_wheel_robot(tmp_path, body))
    assert model.defects == () and messages == []


@pytest.mark.parametrize(("geometry", "mass", "diag"), [
    (Geometry("box", (0.25, 0.16, 0.05)), 1.0, BASE_BOX),
    (Geometry("cylinder", (0.025, 0.02)), 0.1, CYLINDER),
    (Geometry("sphere", (0.1,)), 2.0, (0.008, 0.008, 0.008)),
])
def test_shape_inertia(geometry: Geometry, mass: float, diag) -> None:
    np.testing.assert_allclose(shape_inertia(mass, geometry), np.diag(diag), rtol=1e-12)


def test_mesh_has_no_computed_inertia() -> None:
    assert shape_inertia(1.0, Geometry("mesh", (1, 1, 1), "wheel.stl")) is None


def test_the_env_refuses_a_non_physical_model(shipped_model, tmp_path: Path) -> None:
    """It used to warn and simulate: the car was 94 m away after 3 s of standing still."""
    import gymnasium as gym

    import smartcar_gym  # noqa: F401  (registers SmartCar-v0)

    text = shipped_model.urdf
    head = text.index('<link name="head"')
    mass = text.index('<mass value="', head)
    path = tmp_path / "negative_head.urdf"
    path.write_text(text[:mass] + '<mass value="-1' + text[text.index('"', mass + 13):])
    line = path.read_text()[:head].count("\n") + 1
    with pytest.raises(ModelError) as info:
        gym.make("SmartCar-v0", model=str(path))
    assert str(info.value).startswith(f"{path}:{line}: non-physical model, cannot be simulated")
    assert str(info.value).endswith("link 'head': non-positive mass: mass -1 kg; expected > 0")


def test_a_non_physical_model_object_is_not_simulated(tmp_path: Path) -> None:
    """inspect_model() hands a non-physical model out for reports; the robot refuses it."""
    path = write_one_wheel_robot(
        tmp_path, '<inertial><mass value="-1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" '
                  'izz="1"/></inertial>')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = inspect_model(path)
    import gymnasium as gym

    import smartcar_gym  # noqa: F401

    with pytest.raises(ModelError, match=r"robot\.urdf: non-physical model, cannot be simulated: "
                                         r"arm/inertial: non-positive mass: mass -1 kg"):
        gym.make("SmartCar-v0", model=model)
