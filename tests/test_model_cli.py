"""The ``smartcar-model`` command: urdf, check, show; exit codes and one-line errors.

Exit status, every command: 0 OK; 1 ``check`` loaded the model and found errors (or, with
--strict, defects); 2 the model could not be loaded or the command could not run.
"""

from __future__ import annotations

import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import imageio.v3 as iio
import pytest

from smartcar_gym.model import SHIPPED_MODEL
from smartcar_gym.model_cli import main

FIXTURES = Path(__file__).parent / "fixtures"
SEEDLIKE = FIXTURES / "seedlike.urdf"
LEGACY = FIXTURES / "legacy" / "smartcar_description" / "urdf" / "smartcar.urdf.xacro"
SEED_PKG = FIXTURES / "seed" / "smartcar_description"
MESHBOT = FIXTURES / "meshbot_description" / "urdf" / "meshbot.urdf"


def run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_urdf_prints_the_expanded_urdf(capsys) -> None:
    code, out, err = run(capsys, "urdf")
    assert (code, err) == (0, "")
    root = ET.fromstring(out.split("?>", 1)[1])
    assert root.tag == "robot"
    assert [e.get("name") for e in root.findall("link")] == [
        "base_link", "left_front_wheel", "right_front_wheel", "left_back_wheel",
        "right_back_wheel", "head"]


def test_urdf_to_file_with_package_path_args_and_warnings(capsys, tmp_path: Path) -> None:
    target = tmp_path / "out" / "car.urdf"
    code, out, err = run(capsys, "urdf", str(LEGACY), "--package-path", str(FIXTURES / "legacy"),
                         "--arg", "with_head:=false", "-o", str(target))
    assert (code, out) == (0, "")
    root = ET.parse(target).getroot()
    assert len(root.findall("link")) == 5
    lines = err.splitlines()
    assert len(lines) == 3
    assert all(line.startswith("smartcar-model: warning: ") for line in lines)
    assert "ROS-indigo xacro: added the xacro: prefix to tags <arg>" in lines[0]


def test_check_clean_model_exits_0(capsys) -> None:
    code, out, err = run(capsys, "check")
    assert (code, err) == (0, "")
    assert "root    base_link; 6 links, 5 joints" in out
    shipped = Path(SHIPPED_MODEL).parents[1]
    assert f"packages\n  smartcar_description -> {shipped}\n\nlinks" in out
    assert "  left_front_wheel_joint   left   0.025     0.08 0.08 0.025    +1" in out
    assert "wheel radius 0.025 m, track width 0.16 m" in out
    assert "defects (0)\n  none" in out
    assert out.rstrip().endswith("result: OK (0 errors, 0 warnings, 0 repairs)")


def test_check_seed_style_model_warns_repairs_and_exits_0(capsys) -> None:
    code, out, _ = run(capsys, "check", str(SEEDLIKE))
    assert code == 0
    assert "links (after repairs)" in out
    assert "defects (17)" in out and "repairs (16)" in out
    assert "  head/collision: origin xyz 0.08 0 0.08 rpy 0 0 0 -> xyz 0 0 0 rpy 0 0 0" in out
    assert out.rstrip().endswith("result: OK (0 errors, 17 warnings, 16 repairs)")


def test_check_the_tutorial_files_without_package_path(capsys) -> None:
    code, out, _ = run(capsys, "check", str(SEED_PKG / "urdf" / "smartcar.urdf.xacro"))
    assert code == 0
    assert f"packages\n  smartcar_description -> {SEED_PKG}\n" in out  # not the shipped one
    assert "notes\n  " + str(SEED_PKG / "urdf" / "smartcar.urdf.xacro") in out  # legacy tags
    assert out.rstrip().endswith("result: OK (0 errors, 17 warnings, 16 repairs)")


def test_check_a_urdf_without_packages_says_none(capsys) -> None:
    code, out, _ = run(capsys, "check", str(SEEDLIKE))
    assert code == 0
    assert "packages\n  none\n" in out


def test_check_strict_fails_on_any_defect(capsys) -> None:
    code, out, _ = run(capsys, "check", str(SEEDLIKE), "--strict")
    assert code == 1
    assert out.rstrip().endswith("result: FAILED (0 errors, 17 warnings, 16 repairs, strict)")


def test_check_error_defect_exits_1(capsys, tmp_path: Path) -> None:
    path = tmp_path / "light.urdf"
    path.write_text(SEEDLIKE.read_text().replace('<mass value="0.1" />', '<mass value="0" />', 1))
    code, out, _ = run(capsys, "check", str(path), "--no-repair")
    assert code == 1
    assert "error: non-positive mass: left_front_wheel/inertial: mass 0 kg; expected > 0" in out
    assert out.rstrip().endswith("result: FAILED (1 errors, 16 warnings, 0 repairs)")


def test_check_a_repaired_error_passes_as_load_model_does(capsys, tmp_path: Path) -> None:
    path = tmp_path / "flipped.urdf"  # base_link izz -0.001: repaired from its box collision
    text = SEEDLIKE.read_text()
    base = text.index('<link name="base_link"')
    inertia = text.index('izz="', base)
    path.write_text(text[:inertia] + 'izz="-0.001' + text[text.index('"', inertia + 5):])
    code, out, _ = run(capsys, "check", str(path))
    assert code == 0  # was 1 (FAILED), while load_model and the env took the repaired model
    assert "error: non-positive-definite inertia: base_link/inertia" in out
    assert out.rstrip().endswith("result: OK (0 errors, 16 warnings, 16 repairs, 1 errors "
                                 "repaired)")
    code, out, _ = run(capsys, "check", str(path), "--no-repair")
    assert code == 1
    assert out.rstrip().endswith("result: FAILED (1 errors, 16 warnings, 0 repairs)")


def test_urdf_still_works_on_a_non_physical_model(capsys, tmp_path: Path) -> None:
    path = tmp_path / "light.urdf"
    path.write_text(SEEDLIKE.read_text().replace('<mass value="0.1" />', '<mass value="0" />', 1))
    code, out, err = run(capsys, "urdf", str(path))
    assert code == 0 and out.startswith("<?xml")
    assert ("smartcar-model: warning: light.urdf: error: non-positive mass: "
            "left_front_wheel/inertial: mass 0 kg; expected > 0\n") in err


def test_check_model_error_exits_2_with_one_line(capsys) -> None:
    code, out, err = run(capsys, "check", str(LEGACY), "--package-path",
                         str(FIXTURES / "legacy"), "--no-legacy", "--arg", "with_head:=1")
    assert (code, out) == (2, "")
    assert err.count("\n") == 1
    assert err.startswith(f"smartcar-model: error: {LEGACY} (xacro output):")
    assert "has no links: the file uses unprefixed xacro tags <arg>" in err


@pytest.mark.parametrize("command", ["check", "urdf", "show"])
def test_missing_file_exits_2_with_one_line(capsys, tmp_path: Path, command: str) -> None:
    output = ["-o", str(tmp_path / "x.png")] if command == "show" else []
    code, out, err = run(capsys, command, str(tmp_path / "none.urdf"), *output)
    assert (code, out) == (2, "")
    assert err == f"smartcar-model: error: no such robot description: {tmp_path}/none.urdf\n"


@pytest.mark.parametrize("command", ["check", "urdf", "show"])
def test_model_error_exits_2_for_every_command(capsys, tmp_path: Path, command: str) -> None:
    path = tmp_path / "bad.urdf"
    path.write_text("<robot name='r'>\n<link name='a'>\n</robot>\n")
    extra = ["-o", str(tmp_path / "x.png")] if command == "show" else []
    code, out, err = run(capsys, command, str(path), *extra)
    assert (code, out) == (2, "")
    assert err == (f"smartcar-model: error: {path}:3: XML syntax error: mismatched tag "
                   "(column 3); expected well-formed XML\n")
    assert not (tmp_path / "x.png").exists()


def test_usage_errors_exit_2(capsys) -> None:
    with pytest.raises(SystemExit) as info:
        main(["show"])  # -o is required
    assert info.value.code == 2
    with pytest.raises(SystemExit):
        main(["urdf", "--arg", "novalue"])
    assert "expected NAME:=VALUE, got 'novalue'" in capsys.readouterr().err


def test_show_writes_a_png_of_the_requested_size(capfd, tmp_path: Path) -> None:
    target = tmp_path / "car.png"
    code, out, err = run(capfd, "show", "-o", str(target), "--width", "160", "--height", "120")
    assert (code, out, err) == (0, "", "")
    image = iio.imread(target)
    assert image.shape == (120, 160, 3)
    blue = (image[:, :, 2] > 120) & (image[:, :, 0] < 60) & (image[:, :, 1] < 60)
    assert blue.sum() > 500  # the blue base box is in the picture
    black = image.sum(axis=2) < 40
    assert black.sum() > 20  # and black wheels


def test_show_a_model_with_package_meshes(capfd, tmp_path: Path) -> None:
    target = tmp_path / "meshbot.png"
    code, out, err = run(capfd, "show", str(MESHBOT), "-o", str(target), "--width", "160",
                         "--height", "120", "--settle", "0.5")
    assert (code, out, err) == (0, "", "")  # no pybullet messages on the C-level fds either
    assert iio.imread(target).shape == (120, 160, 3)


def test_show_bad_size_is_an_error(capsys, tmp_path: Path) -> None:
    code, _, err = run(capsys, "show", "-o", str(tmp_path / "x.png"), "--width", "0")
    assert code == 2
    assert err == "smartcar-model: error: --width/--height must be positive, got 0x480\n"


def test_console_script_module_runs_without_traceback(tmp_path: Path) -> None:
    result = subprocess.run([sys.executable, "-m", "smartcar_gym.model_cli", "check",
                             str(tmp_path / "none.urdf")], capture_output=True, text=True,
                            check=False)
    assert result.returncode == 2
    assert result.stderr.startswith("smartcar-model: error: no such robot description")
    assert "Traceback" not in result.stderr


def test_help_documents_the_exit_status(capsys) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert "exit status (every command):\n  0  OK\n  1  check: the model loaded, but has " \
           "errors" in out
    assert "  2  the model could not be loaded or the command could not run" in out
