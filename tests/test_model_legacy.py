"""ROS-indigo xacro (unprefixed tags) is upgraded and expands like the modern description."""

from __future__ import annotations

import warnings
import xml.dom.minidom
from pathlib import Path

import pytest
import xacro

from smartcar_gym.model import LegacyXacroWarning, ModelError, XacroWarning, load_model
from smartcar_gym.model.legacy import LEGACY_TAGS, upgrade_tags

FIXTURES = Path(__file__).parent / "fixtures"
LEGACY_PKG = FIXTURES / "legacy" / "smartcar_description"
LEGACY_MAIN = LEGACY_PKG / "urdf" / "smartcar.urdf.xacro"


def load_legacy(**kwargs):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = load_model(LEGACY_MAIN, package_path=[FIXTURES / "legacy"], **kwargs)
    return model, [w for w in caught if issubclass(w.category, LegacyXacroWarning)]


@pytest.fixture(scope="module")
def modern():
    return load_model()


def test_legacy_fixture_expands_to_the_modern_robot(modern) -> None:
    legacy, _ = load_legacy()
    assert list(legacy.links) == list(modern.links)
    assert list(legacy.joints) == list(modern.joints)
    assert legacy.links == modern.links  # masses, inertias, geometry, origins
    for name, joint in modern.joints.items():
        other = legacy.joints[name]
        assert (other.type, other.parent, other.child) == (joint.type, joint.parent, joint.child)
        assert other.origin == joint.origin
        assert other.axis == joint.axis
    assert legacy.wheels == modern.wheels
    assert legacy.defects == ()
    assert "Gazebo/FlatBlack" in legacy.urdf  # the unprefixed gazebo macros ran too


def test_one_legacy_warning_per_file_naming_file_and_tags() -> None:
    _, caught = load_legacy()
    messages = {Path(str(w.message).split(": ")[0]).name: str(w.message) for w in caught}
    assert len(caught) == 3
    assert sorted(messages) == ["gazebo.urdf.xacro", "smartcar.urdf.xacro",
                                "smartcar_body.urdf.xacro"]
    main = messages["smartcar.urdf.xacro"]
    assert main.startswith(f"{LEGACY_MAIN}: ROS-indigo xacro: added the xacro: prefix to ")
    assert "tags <arg>, <include>, <if>, <unless>" in main
    assert "macro calls <smartcar_body/>, <smartcar_head/>, <smartcar_sim/>" in main
    body = messages["smartcar_body.urdf.xacro"]
    assert "tags <property>, <include>, <macro>, <insert_block>" in body
    assert "macro calls <box_inertia/>, <wheel/>, <cylinder_inertia/>" in body
    assert "tags <macro> and macro calls <gazebo_material/>" in messages["gazebo.urdf.xacro"]
    assert all(issubclass(w.category, FutureWarning) for w in caught)  # shown to users


@pytest.mark.parametrize(("mappings", "links", "red"), [
    (None, 6, False),
    ({"with_head": "true"}, 6, False),
    ({"with_head": "false"}, 5, True),
    ({"with_head": 0}, 5, True),
])
def test_arg_if_unless_follow_mappings(mappings, links: int, red: bool) -> None:
    model, _ = load_legacy(mappings=mappings)
    assert len(model.links) == links
    assert ("head" in model.links) is (links == 6)
    assert ("Gazebo/Red" in model.urdf) is red  # the <unless> branch


def test_without_legacy_upgrade_the_robot_has_no_links_and_the_error_says_why() -> None:
    with pytest.raises(ModelError) as info:
        load_model(LEGACY_MAIN, package_path=[FIXTURES / "legacy"], legacy=False,
                   mappings={"with_head": "true"})
    message = str(info.value)
    assert message.startswith(f"{LEGACY_MAIN} (xacro output):")
    assert "robot 'smartcar' has no links: the file uses unprefixed xacro tags <arg>, " \
           "<include>, <if>, <unless>" in message
    assert "unprefixed macro calls <smartcar_body/>, <smartcar_sim/>" in message
    assert "today's xacro ignores" in message


def test_without_legacy_upgrade_the_unprefixed_arg_is_undefined() -> None:
    with pytest.raises(ModelError) as info:
        load_model(LEGACY_MAIN, package_path=[FIXTURES / "legacy"], legacy=False)
    assert str(info.value) == f"{LEGACY_MAIN}:12: xacro: Undefined substitution argument with_head"


def test_plain_urdf_with_unprefixed_xacro_tags(tmp_path: Path) -> None:
    path = tmp_path / "robot.urdf"
    path.write_text('<robot name="r">\n  <property name="w" value="1"/>\n'
                    '  <macro name="m"><link name="a"/></macro>\n  <m/>\n</robot>\n')
    with pytest.raises(ModelError) as info:
        load_model(path)
    assert str(info.value) == (
        f"{path}:1: robot 'r' has no links: the file uses unprefixed xacro tags <property>, "
        "<macro> and unprefixed macro calls <m/> that today's xacro ignores; let them be "
        "upgraded (legacy=True, the default) or write them as <xacro:...>")


def test_plain_urdf_with_xacro_tags_asks_for_xacro(tmp_path: Path) -> None:
    path = tmp_path / "robot.urdf"
    path.write_text('<robot name="r" xmlns:xacro="http://ros.org/wiki/xacro">\n'
                    '  <xacro:macro name="m"><link name="a"/></xacro:macro>\n</robot>\n')
    with pytest.raises(ModelError, match="unexpanded <xacro:...> tags; load it through xacro"):
        load_model(path)


@pytest.mark.parametrize(("tag", "attribute"), sorted(LEGACY_TAGS.items()))
def test_upgrade_tags_renames_each_legacy_tag(tag: str, attribute: str) -> None:
    doc = xml.dom.minidom.parseString(
        f'<robot xmlns:xacro="http://ros.org/wiki/xacro"><link name="a"><{tag} {attribute}="x"/>'
        f'</link><{tag}/></robot>')
    assert upgrade_tags(doc) == [tag]
    renamed, bare = doc.getElementsByTagName(f"xacro:{tag}") + doc.getElementsByTagName(tag)
    assert renamed.getAttribute(attribute) == "x"
    assert bare.parentNode.tagName == "robot"  # without its attribute it is not xacro


def test_element_call_and_attribute_tags_expand(tmp_path: Path) -> None:
    path = tmp_path / "robot.urdf.xacro"
    path.write_text("""<robot name="r" xmlns:xacro="http://ros.org/wiki/xacro">
  <property name="shape" value="sphere"/>
  <macro name="wheel" params="side y">
    <link name="${side}"><collision><geometry>
      <element xacro:name="${shape}"><attribute name="radius" value="0.04"/></element>
    </geometry></collision></link>
    <joint name="${side}_joint" type="continuous"><parent link="base_link"/>
      <child link="${side}"/><origin xyz="0 ${y} 0"/><axis xyz="0 1 0"/></joint>
  </macro>
  <link name="base_link"/>
  <call macro="wheel" side="left" y="0.1"/>
  <wheel side="right" y="-0.1"/>
</robot>
""")
    with pytest.warns(LegacyXacroWarning, match="<property>, <macro>, <element>, <attribute>, "
                                                "<call> and macro calls <wheel/>"):
        model = load_model(path)
    assert model.links["left"].collisions[0].geometry.type == "sphere"
    assert model.wheel_radius_m == 0.04
    assert [(w.joint, w.side) for w in model.wheels] == [("left_joint", "left"),
                                                         ("right_joint", "right")]


def test_urdf_element_names_are_never_taken_for_macro_calls(tmp_path: Path) -> None:
    path = tmp_path / "robot.urdf.xacro"
    path.write_text("""<robot name="r" xmlns:xacro="http://ros.org/wiki/xacro">
  <xacro:macro name="inertia"><oops/></xacro:macro>
  <link name="a"><inertial><mass value="1"/>
    <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
</robot>
""")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with pytest.raises(ModelError, match="no drivable wheels"):
            load_model(path)
    assert not [w for w in caught if issubclass(w.category, LegacyXacroWarning)]


def test_xacro_stderr_messages_become_warnings(tmp_path: Path, capfd) -> None:
    path = tmp_path / "robot.urdf.xacro"
    path.write_text('<robot name="r" xmlns:xacro="http://ros.org/wiki/xacro">\n'
                    '  <xacro:property name="p" value="1" colour="red"/>\n'
                    '  <link name="a"/>\n</robot>\n')
    with pytest.warns(XacroWarning, match=r"xacro: xacro:property: unknown attribute\(s\): "
                                          "colour"), pytest.raises(ModelError):
        load_model(path)
    assert capfd.readouterr().err == ""


def test_xacro_globals_are_restored_after_success_and_failure(tmp_path: Path) -> None:
    before = (xacro.parse, xacro.handle_macro_call, xacro.print_location, xacro.color.message,
              xacro.verbosity, list(xacro.all_includes))
    load_legacy()
    bad = tmp_path / "bad.xacro"
    bad.write_text('<robot name="r" xmlns:xacro="http://ros.org/wiki/xacro">${nope}</robot>')
    with pytest.raises(ModelError):
        load_model(bad)
    after = (xacro.parse, xacro.handle_macro_call, xacro.print_location, xacro.color.message,
             xacro.verbosity, list(xacro.all_includes))
    assert after == before


def test_concurrent_loads_do_not_mix_up_xacro_state(modern) -> None:
    from concurrent.futures import ThreadPoolExecutor

    def job(i: int):
        if i % 2:
            return load_model(LEGACY_MAIN, package_path=[FIXTURES / "legacy"])
        return load_model()

    with warnings.catch_warnings():  # process-wide: set once, around all threads
        warnings.simplefilter("ignore")
        with ThreadPoolExecutor(max_workers=4) as pool:
            models = list(pool.map(job, range(8)))
    assert all(m.links == modern.links and m.joints == modern.joints for m in models)
