"""The tutorial's own three xacro files (fixtures/seed, byte for byte): upgraded and repaired."""

from __future__ import annotations

import hashlib
import warnings
from pathlib import Path

import pytest

from smartcar_gym.model import LegacyXacroWarning, ModelDefectWarning, load_model
from smartcar_gym.model.defects import DUPLICATED_ORIGIN, GEOMETRY_MISMATCH, IMPLAUSIBLE_INERTIA

SEED_PKG = Path(__file__).parent / "fixtures" / "seed" / "smartcar_description"
SEED = SEED_PKG / "urdf" / "smartcar.urdf.xacro"
#: sha256 of the files as published by the tutorial: the fixture must never be "fixed"
SHA256 = {
    "gazebo.urdf.xacro": "29bebdcc25a1160368ae252466bf5475b591fd992b1aa27153c0eb1a608c4b5f",
    "smartcar.urdf.xacro": "42f71f68c7ea8e676ca70a071e700e3ce231fa8e4951b56489fa96d3375e2d9b",
    "smartcar_body.urdf.xacro": "d7114f56a37ccd6a9bb885beb5ff5ae789be06ecfb9688fcd6edc7ebc24ee4b8",
}
WHEELS = ["left_front_wheel", "right_front_wheel", "left_back_wheel", "right_back_wheel"]


def load_seed(**kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = load_model(SEED, **kwargs)
    return model, caught


@pytest.fixture(scope="module")
def seed():
    return load_seed()


def test_the_fixture_is_the_tutorial_byte_for_byte() -> None:
    files = {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
             for p in (SEED_PKG / "urdf").iterdir()}
    assert files == SHA256
    assert sorted(p.name for p in SEED_PKG.iterdir()) == ["urdf"]  # no package.xml, as published


def test_one_legacy_warning_per_upgraded_file(seed) -> None:
    _, caught = seed
    legacy = [str(w.message) for w in caught if w.category is LegacyXacroWarning]
    assert legacy == [
        f"{SEED}: ROS-indigo xacro: added the xacro: prefix to tags <include> and macro calls "
        "<smartcar_body/>, <smartcar_sim/> (today's xacro ignores unprefixed tags); update the "
        "file",
        f"{SEED_PKG / 'urdf' / 'smartcar_body.urdf.xacro'}: ROS-indigo xacro: added the xacro: "
        "prefix to tags <property>, <include> (today's xacro ignores unprefixed tags); update "
        "the file",
    ]  # gazebo.urdf.xacro already writes <xacro:macro>


def test_the_seed_expands_to_the_tutorial_robot(seed) -> None:
    model, _ = seed
    assert model.packages == {"smartcar_description": SEED_PKG}
    assert list(model.links) == ["base_link", *WHEELS, "head"]
    assert [w.joint for w in model.wheels] == [f"{w}_joint" for w in WHEELS]
    assert (model.wheel_radius_m, model.track_width_m) == (0.025, pytest.approx(0.16))
    assert "Gazebo/FlatBlack" in model.urdf  # <smartcar_sim/> from gazebo.urdf.xacro ran


def test_defects_are_reported_and_the_undrivable_ones_repaired(seed) -> None:
    model, caught = seed
    kinds = [d.kind for d in model.defects]
    assert (kinds.count(DUPLICATED_ORIGIN), kinds.count(IMPLAUSIBLE_INERTIA),
            kinds.count(GEOMETRY_MISMATCH)) == (10, 6, 1)
    assert len(model.repairs) == 16  # all but the head's cylinder-under-a-box mismatch
    assert sum(w.category is ModelDefectWarning for w in caught) == 17
    for link in WHEELS:
        assert model.links[link].collisions[0].origin.xyz == (0.0, 0.0, 0.0)
        assert model.links[link].inertial.inertia[2][2] == pytest.approx(0.1 * 0.025**2 / 2)


def test_unrepaired_the_seed_keeps_its_bugs() -> None:
    model, _ = load_seed(repair=False)
    assert model.repairs == ()
    assert len(model.defects) == 17
    assert model.links["left_front_wheel"].collisions[0].origin.xyz == (0.08, 0.08, 0.025)
    assert model.links["base_link"].inertial.inertia[0][0] == 1.0
