"""Every way a description can fail to load, with the message the user gets."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest

from smartcar_gym.model import SHIPPED_MODEL, LegacyXacroWarning, ModelError, load_model

XACRO_NS = 'xmlns:xacro="http://ros.org/wiki/xacro"'


def wheel(name: str, y: float, *, radius: float = 0.03, joint_type: str = "continuous",
          axis: str = "0 1 0", shape: str | None = None) -> str:
    shape = shape or f'<cylinder radius="{radius}" length="0.02"/>'
    return (f'  <link name="{name}"><collision><origin rpy="1.5707963 0 0"/><geometry>{shape}'
            f'</geometry></collision></link>\n'
            f'  <joint name="{name}_joint" type="{joint_type}"><parent link="base"/>'
            f'<child link="{name}"/><origin xyz="0 {y} 0"/><axis xyz="{axis}"/></joint>\n')


def urdf(tmp_path: Path, body: str, name: str = "robot.urdf") -> Path:
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<robot name="r" {XACRO_NS}>\n'
                    f'  <link name="base"/>\n{body}</robot>\n')
    return path


def test_missing_file_is_a_file_not_found_error(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="no such robot description: .*nope.urdf"):
        load_model(tmp_path / "nope.urdf")


@pytest.mark.parametrize("suffix", [".urdf", ".urdf.xacro"])
def test_xml_syntax_error_has_file_and_line(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"broken{suffix}"
    path.write_text('<robot name="r">\n  <link name="a">\n  </lnk>\n</robot>\n')
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == (f"{path}:3: XML syntax error: mismatched tag (column 5); "
                               "expected well-formed XML")
    assert (info.value.file, info.value.line) == (str(path), 3)


def test_xml_syntax_error_in_an_included_file(tmp_path: Path) -> None:
    (tmp_path / "inc.xacro").write_text(f'<robot {XACRO_NS}>\n\n  <link name="x">\n</robot>\n')
    top = urdf(tmp_path, '  <xacro:include filename="inc.xacro"/>\n', "top.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(top)
    assert str(info.value) == (
        f"{tmp_path / 'inc.xacro'}:4: XML syntax error: mismatched tag (column 3); expected "
        f"well-formed XML (included from {top})")


def test_unknown_include(tmp_path: Path) -> None:
    top = urdf(tmp_path, '\n  <xacro:include filename="$(find smartcar_description)/urdf/'
                         'nothere.xacro"/>\n', "top.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(top)
    missing = SHIPPED_MODEL.parent / "nothere.xacro"
    assert str(info.value) == (f"{top}:5: cannot read included file {missing}: "
                               "No such file or directory")


def test_undefined_property_in_expression_names_file_line_and_macro(tmp_path: Path) -> None:
    path = urdf(tmp_path, '  <xacro:property name="w" value="0.1"/>\n'
                          '  <xacro:macro name="m" params="">\n'
                          '    <link name="a"><visual><geometry>'
                          '<sphere radius="${w * scale}"/></geometry></visual></link>\n'
                          '  </xacro:macro>\n  <xacro:m/>\n', "expr.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == (f"{path}:6: xacro: name 'scale' is not defined when evaluating "
                               "expression 'w * scale' (while expanding macro m)")


def test_unknown_macro(tmp_path: Path) -> None:
    path = urdf(tmp_path, '  <xacro:wheel side="left"/>\n', "m.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == f"{path}:4: xacro: unknown macro name: xacro:wheel"


def test_undefined_xacro_argument_and_mapping(tmp_path: Path) -> None:
    path = urdf(tmp_path, '  <link name="$(arg part)"/>\n', "a.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == f"{path}:4: xacro: Undefined substitution argument part"
    with pytest.raises(ModelError, match="expected exactly one root link .*found 2: base, arm"):
        load_model(path, mappings={"part": "arm"})


def test_root_must_be_robot(tmp_path: Path) -> None:
    path = tmp_path / "model.urdf"
    path.write_text('<?xml version="1.0"?>\n<sdf version="1.6"><model name="m"/></sdf>\n')
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == f"{path}:2: root element is <sdf>; expected <robot>"


def test_no_links(tmp_path: Path) -> None:
    path = tmp_path / "empty.urdf.xacro"
    path.write_text(f'<robot name="r" {XACRO_NS}>\n  <xacro:property name="a" value="1"/>\n'
                    '</robot>\n')
    with pytest.raises(ModelError, match=r"empty.urdf.xacro \(xacro output\):\d+: robot has no "
                                         r"links: no <link> elements \(after xacro expansion\); "
                                         r"expected at least one <link name=...> in <robot>"):
        load_model(path)


def test_joint_naming_a_missing_link(tmp_path: Path) -> None:
    path = urdf(tmp_path, wheel("left", 0.1) + '  <joint name="bad" type="fixed">\n'
                          '    <parent link="base"/>\n    <child link="camera"/>\n  </joint>\n')
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == (f"{path}:8: joint 'bad' names child link 'camera', which does "
                               "not exist; expected one of: base, left")


@pytest.mark.parametrize(("body", "line", "expected"), [
    ('  <link/>\n', 4, "link: <link> lacks required attribute 'name'"),
    ('  <link name="a"/>\n  <joint name="j"><parent link="base"/><child link="a"/></joint>\n',
     5, "joint 'j': <joint> lacks required attribute 'type'"),
    ('  <link name="a"/>\n  <joint name="j" type="hinge"><parent link="base"/>'
     '<child link="a"/></joint>\n', 5,
     "joint 'j': type 'hinge'; expected one of revolute, continuous, prismatic, fixed, "
     "floating, planar"),
    ('  <link name="a"/>\n  <joint name="j" type="fixed"><child link="a"/></joint>\n', 5,
     "joint 'j': missing <parent link=...>"),
    ('  <link name="a"><inertial><mass value="1"/></inertial></link>\n', 4,
     "link 'a': <inertial> needs <mass value=...> and <inertia ixx=... izz=...>"),
    ('  <link name="a"><inertial><mass value="1"/><inertia ixx="1" iyy="1" izz="1"/>'
     '</inertial></link>\n', 4, "link 'a': <inertia> lacks required attribute 'ixy'"),
    ('  <link name="a"><visual><geometry><box size="1 2"/></geometry></visual></link>\n', 4,
     "link 'a' <visual>: <box size=\"1 2\">: expected 3 number(s)"),
    ('  <link name="a"><collision><geometry/></collision></link>\n', 4,
     "link 'a' <collision>: expected <geometry> with exactly one of <box>, <cylinder>, "
     "<sphere>, <mesh>, found 0"),
    ('  <link name="a"><collision><geometry><cone radius="1"/></geometry></collision></link>\n',
     4, "link 'a' <collision>: unknown geometry <cone>; expected <box>, <cylinder>, <sphere> "
        "or <mesh>"),
    ('  <link name="a"><collision><geometry><sphere radius="-1"/></geometry></collision>'
     '</link>\n', 4, "link 'a' <collision>: <sphere> dimensions (-1.0,): expected > 0"),
    ('  <link name="a"><visual><origin xyz="0 0 x"/><geometry><sphere radius="1"/></geometry>'
     '</visual></link>\n', 4, "link 'a': <origin xyz=\"0 0 x\">: expected 3 number(s)"),
    ('  <link name="base"/>\n', 4, "link 'base' is defined twice"),
    ('  <link name="a"/>\n', 2, "expected exactly one root link (a link that is no joint's "
                                "child), found 2: base, a"),
    ('  <link name="a"/>\n  <link name="b"/>\n'
     '  <joint name="j1" type="fixed"><parent link="base"/><child link="a"/></joint>\n'
     '  <joint name="j2" type="fixed"><parent link="a"/><child link="a"/></joint>\n', 7,
     "link 'a' is the child of joints 'j1' and 'j2'; expected a tree"),
    ('  <link name="a"/>\n  <joint name="j" type="revolute"><parent link="base"/>'
     '<child link="a"/><axis xyz="0 0 0"/></joint>\n', 5,
     "joint 'j': zero axis; expected a non-zero xyz"),
])
def test_invalid_urdf(tmp_path: Path, body: str, line: int, expected: str) -> None:
    path = urdf(tmp_path, body)
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == f"{path}:{line}: {expected}"


def test_joint_loop_is_reported(tmp_path: Path) -> None:
    path = urdf(tmp_path, '  <link name="a"/>\n  <link name="b"/>\n'
                          '  <joint name="j1" type="fixed"><parent link="a"/><child link="b"/>'
                          '</joint>\n  <joint name="j2" type="fixed"><parent link="b"/>'
                          '<child link="a"/></joint>\n')
    with pytest.raises(ModelError, match="links a, b are not connected to root link 'base' "
                                         r"\(the joints form a loop\); expected a tree"):
        load_model(path)


@pytest.mark.parametrize(("body", "line", "rejected"), [
    ("", None, "no movable joints"),
    (wheel("left", 0.1) + wheel("right", -0.1, joint_type="fixed"), None, "none"),
    (wheel("left", 0.1) + wheel("right", -0.1, axis="0 0 1"), 7,
     "'right_joint' (axis (0, 0, 1) in base is not lateral: |y| <= 0.9)"),
    (wheel("left", 0.1) + wheel("right", -0.1, shape='<box size="0.1 0.1 0.1"/>'), 7,
     "'right_joint' (child link 'right' has no cylinder or sphere collision)"),
    (wheel("left", 0.1) + wheel("mid", 0.0), 7,
     "'mid_joint' (on the centre line y = 0: neither left nor right)"),
    (wheel("left", 0.1) + wheel("right", -0.1, joint_type="prismatic"), 7,
     "'right_joint' (prismatic joint; expected continuous or unlimited revolute)"),
])
def test_no_drivable_wheels(tmp_path: Path, body: str, line: int | None, rejected: str) -> None:
    path = urdf(tmp_path, body)
    with pytest.raises(ModelError) as info:
        load_model(path)
    message = str(info.value)
    assert (info.value.file, info.value.line) == (str(path), line)  # the offending joint's line
    where = str(path) if line is None else f"{path}:{line}"
    assert message.startswith(f"{where}: no drivable wheels: expected at least one left and one "
                              "right wheel (a continuous or unlimited revolute joint whose axis "
                              "is lateral in base and whose child link has a cylinder or sphere "
                              "collision); found left: ")
    assert f"; right: none; rejected: {rejected}" in message
    assert message.endswith("name the wheel joints with wheels={'left': [...], 'right': [...]}")


def test_limited_revolute_is_no_wheel_but_unlimited_is(tmp_path: Path) -> None:
    limited = wheel("right", -0.1, joint_type="revolute").replace(
        "</joint>", '<limit lower="-0.5" upper="0.5" effort="1" velocity="1"/></joint>')
    with pytest.raises(ModelError, match=r"'right_joint' \(revolute with limits; expected "
                                         "continuous or unlimited revolute\\)"):
        load_model(urdf(tmp_path, wheel("left", 0.1) + limited))
    free = wheel("right", -0.1, joint_type="revolute").replace(
        "</joint>", '<limit effort="1" velocity="1"/></joint>')
    model = load_model(urdf(tmp_path, wheel("left", 0.1) + free))
    assert [w.side for w in model.wheels] == ["left", "right"]


def test_no_drivable_wheels_in_a_xacro_file_names_the_xacro_output(tmp_path: Path) -> None:
    path = urdf(tmp_path, wheel("left", 0.1) + wheel("right", -0.1, axis="0 0 1"),
                "r.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert info.value.file == f"{path} (xacro output)"
    assert info.value.line is not None  # the joint's line in the expanded URDF
    assert str(info.value).startswith(f"{path} (xacro output):{info.value.line}: no drivable")


def test_wheel_override_with_unknown_joint_lists_the_joints() -> None:
    with pytest.raises(ModelError) as info:
        load_model(wheels={"left": ["left_front_wheel_joint", "left_wheel"],
                           "right": ["right_front_wheel_joint"]})
    assert str(info.value) == (
        f"{SHIPPED_MODEL} (xacro output): wheels: unknown joint(s) left_wheel; the robot's "
        "joints are: left_front_wheel_joint, right_front_wheel_joint, left_back_wheel_joint, "
        "right_back_wheel_joint, tobox")


def test_wheel_override_naming_an_unfit_joint_gives_its_line(tmp_path: Path) -> None:
    path = urdf(tmp_path, wheel("left", 0.1) + wheel("right", -0.1, axis="0 0 1"))
    with pytest.raises(ModelError) as info:
        load_model(path, wheels={"left": ["left_joint"], "right": ["right_joint"]})
    assert str(info.value) == (f"{path}:7: wheels: joint 'right_joint' (axis (0, 0, 1) in base "
                               "is not lateral: |y| <= 0.9) cannot be a drive wheel")


@pytest.mark.parametrize(("wheels", "expected"), [
    ({"left": ["tobox"], "right": ["right_front_wheel_joint"]},
     "wheels: joint 'tobox' (fixed joint; expected continuous or unlimited revolute) cannot "
     "be a drive wheel"),
    ({"left": ["left_front_wheel_joint"]}, "expected {'left': [joint, ...], 'right': "
                                           "[joint, ...]} with at least one joint per side"),
    ({"left": ["left_front_wheel_joint"], "right": ["right_front_wheel_joint"], "up": []},
     "expected {'left'"),
])
def test_wheel_override_errors(wheels, expected: str) -> None:
    with pytest.raises(ModelError) as info:
        load_model(wheels=wheels)
    assert expected in str(info.value)


def test_wheel_override_selects_and_assigns_sides() -> None:
    model = load_model(wheels={"left": ["left_back_wheel_joint"],
                               "right": ["right_back_wheel_joint"]})
    assert [(w.joint, w.side, w.forward_sign) for w in model.wheels] == [
        ("left_back_wheel_joint", "left", 1), ("right_back_wheel_joint", "right", 1)]
    assert model.track_width_m == pytest.approx(0.16)


def test_mirrored_axis_gives_negative_forward_sign(tmp_path: Path) -> None:
    model = load_model(urdf(tmp_path, wheel("left", 0.1, axis="0 -1 0") + wheel("right", -0.1)))
    assert [(w.side, w.forward_sign) for w in model.wheels] == [("left", -1), ("right", 1)]


def test_different_wheel_radii_have_no_common_radius(tmp_path: Path) -> None:
    path = urdf(tmp_path, wheel("left", 0.1, radius=0.03) + wheel("right", -0.1, radius=0.031))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model = load_model(path)
    assert [w.radius_m for w in model.wheels] == [0.03, 0.031]
    with pytest.raises(ModelError) as info:
        _ = model.wheel_radius_m
    assert str(info.value) == (f"{path}: drive wheels have different radii (left_joint 0.03 m, "
                               "right_joint 0.031 m); expected one common radius within 1 %")
    spheres = urdf(tmp_path, wheel("l", 0.1, shape='<sphere radius="0.05"/>')
                   + wheel("r", -0.1, shape='<sphere radius="0.0502"/>'), "s.urdf")
    assert load_model(spheres).wheel_radius_m == pytest.approx(0.0501)


SEED_PKG = Path(__file__).parent / "fixtures" / "seed" / "smartcar_description"
LATIN1 = '<?xml version="1.0"?>\n<robot name="voiture">\n  <link name="châssis"/>\n</robot>\n'


@pytest.mark.parametrize("suffix", [".urdf", ".urdf.xacro"])
def test_non_utf8_file_names_file_line_and_byte(tmp_path: Path, suffix: str) -> None:
    path = tmp_path / f"latin1{suffix}"
    path.write_bytes(LATIN1.encode("latin-1"))
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == (f"{path}:3: not UTF-8 text: byte 0xe2 (column 17) cannot be "
                               "decoded (invalid continuation byte); expected a UTF-8 encoded "
                               "file (re-save it as UTF-8)")


def test_non_utf8_included_file_is_the_one_named(tmp_path: Path) -> None:
    (tmp_path / "inc.xacro").write_bytes(LATIN1.encode("latin-1"))
    top = urdf(tmp_path, '  <xacro:include filename="inc.xacro"/>\n', "top.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(top)
    assert (info.value.file, info.value.line) == (str(tmp_path / "inc.xacro"), 3)
    assert "not UTF-8 text: byte 0xe2" in str(info.value)


def test_unset_environment_variable(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SMARTCAR_TEST_PART", raising=False)
    path = urdf(tmp_path, '  <link name="$(env SMARTCAR_TEST_PART)"/>\n'
                          '  <joint name="j" type="fixed"><parent link="base"/>'
                          '<child link="$(env SMARTCAR_TEST_PART)"/></joint>\n'
                + wheel("left", 0.1) + wheel("right", -0.1), "env.urdf.xacro")
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == (
        f"{path}:4: xacro: environment variable 'SMARTCAR_TEST_PART' is not set (asked for by "
        "$(env SMARTCAR_TEST_PART)); expected it set, or $(optenv SMARTCAR_TEST_PART default) "
        "in the file")
    monkeypatch.setenv("SMARTCAR_TEST_PART", "camera")
    assert "camera" in load_model(path).links


def seed_copy(tmp_path: Path) -> Path:
    """A copy of the tutorial's package (no package.xml, like the original): its main file."""
    copy = tmp_path / "smartcar_description" / "urdf"
    copy.mkdir(parents=True)
    for file in (SEED_PKG / "urdf").iterdir():
        (copy / file.name).write_bytes(file.read_bytes())
    return copy / "smartcar.urdf.xacro"


def test_misspelled_legacy_macro_call_lists_the_defined_macros(tmp_path: Path) -> None:
    top = seed_copy(tmp_path)
    top.write_text(top.read_text().replace("<smartcar_body/>", "<smartcar_bdy/>"))
    with pytest.warns(LegacyXacroWarning), pytest.raises(ModelError) as info:
        load_model(top)
    assert str(info.value) == (
        f"{top}:23: robot 'smartcar' has no links: no macro is defined for <smartcar_bdy/>, so "
        "xacro kept it as plain XML; defined macros: smartcar_sim, smartcar_body; expected a "
        "call of a defined macro (misspelled?)")
    with pytest.raises(ModelError, match="let them be upgraded"):  # not upgraded: that hint
        load_model(top, legacy=False)


def test_a_file_that_defines_macros_but_never_calls_them() -> None:
    body = SEED_PKG / "urdf" / "smartcar_body.urdf.xacro"
    with pytest.warns(LegacyXacroWarning), pytest.raises(ModelError) as info:
        load_model(body)
    assert str(info.value) == (
        f"{body}:11: robot 'smartcar' has no links: the file defines macros smartcar_sim, "
        "smartcar_body but never calls one (it is meant to be included); expected a call such "
        "as <xacro:smartcar_body/>, or load the file that includes and calls it")
    gazebo = SEED_PKG / "urdf" / "gazebo.urdf.xacro"
    with pytest.raises(ModelError, match="defines macro smartcar_sim but never calls it"):
        load_model(gazebo)


@pytest.mark.parametrize("chain", [["a.xacro"], ["a.xacro", "b.xacro"], ["a.xacro", "b.xacro",
                                                                         "c.xacro"]])
def test_include_cycle_names_the_files_in_it(tmp_path: Path, chain: list[str]) -> None:
    for i, name in enumerate(chain):
        nxt = chain[(i + 1) % len(chain)]
        link = '  <link name="base"/>\n' if i == 0 else ""
        (tmp_path / name).write_text(f'<?xml version="1.0"?>\n<robot name="r" {XACRO_NS}>\n'
                                     f'  <xacro:include filename="{nxt}"/>\n{link}</robot>\n')
    with pytest.raises(ModelError) as info:  # was a RecursionError, no file named
        load_model(tmp_path / "a.xacro")
    files = " -> ".join(str(tmp_path / n) for n in [*chain, chain[0]])
    assert str(info.value) == (
        f"{tmp_path / chain[-1]}:3: xacro include cycle: {files} (each file includes the next), "
        "so the expansion never ends; expected no file to include itself, directly or through "
        "others")
    assert info.value.__cause__ is None and info.value.__suppress_context__


def test_macro_recursion_names_the_macros(tmp_path: Path) -> None:
    path = urdf(tmp_path, '  <xacro:macro name="foo"><xacro:bar/></xacro:macro>\n'
                          '  <xacro:macro name="bar"><xacro:foo/></xacro:macro>\n'
                          '  <xacro:foo/>\n', "loop.urdf.xacro")
    with pytest.raises(ModelError) as info:  # was a 1500-character "foo -> bar -> foo ..."
        load_model(path)
    assert str(info.value) == (f"{path}:5: xacro macro recursion: foo -> bar -> foo calls "
                               "itself without end; expected the recursion to stop (a "
                               "<xacro:if> around the inner call)")
