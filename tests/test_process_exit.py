"""process_exit.exit_now: the commands' processes end without Python's teardown, and with
everything Python's exit would have done before it (threads, atexit, flushed streams)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

CHILD = textwrap.dedent("""
    import atexit, ctypes, pathlib, sys, tempfile, threading, time
    from smartcar_gym.agents.process_exit import exit_now

    out = pathlib.Path(sys.argv[1])
    kept = tempfile.TemporaryDirectory()  # removed by its weakref finalizer, at exit
    (out / "tmpdir").write_text(kept.name)
    atexit.register(lambda: (out / "atexit").write_text("ran"))

    def late():
        time.sleep(0.3)
        (out / "thread").write_text("done")

    threading.Thread(target=late).start()  # not a daemon: the exit waits for it
    sys.stdout.write("from python;")  # no newline into a pipe: still in the buffer
    ctypes.CDLL(None).printf(b"from c;")  # in the C library's buffer
    code = sys.argv[2]
    exit_now(None if code == "none" else int(code))
    (out / "after").write_text("exit_now returned")
""")


def _run(tmp_path: Path, code: str, fast: bool = True) -> subprocess.CompletedProcess:
    env = dict(os.environ, SMARTCAR_GYM_FAST_EXIT="1" if fast else "0")
    env.pop("PYTHONUNBUFFERED", None)  # it would unbuffer C's stdout as well as Python's
    return subprocess.run([sys.executable, "-c", CHILD, str(tmp_path), code], env=env,
                          capture_output=True, text=True, timeout=60)


@pytest.mark.skipif(sys.platform == "win32", reason="the C library is loaded by name")
@pytest.mark.parametrize("fast", [True, False], ids=["os._exit", "sys.exit"])
@pytest.mark.parametrize(("code", "expected"), [("3", 3), ("0", 0), ("none", 0)])
def test_exit_now_does_what_pythons_exit_does_first(tmp_path, code, expected, fast):
    proc = _run(tmp_path, code, fast)
    assert proc.returncode == expected, proc.stderr
    assert "from python;" in proc.stdout and "from c;" in proc.stdout
    assert (tmp_path / "atexit").read_text() == "ran"
    assert (tmp_path / "thread").read_text() == "done"
    assert not Path((tmp_path / "tmpdir").read_text()).exists()
    assert not (tmp_path / "after").exists()
