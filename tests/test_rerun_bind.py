"""What ``smartcar-eval --rerun-serve`` listens on: this machine only (127.0.0.1) by default,
the address of ``--rerun-bind`` when asked. The listening sockets are read from the kernel
(``/proc/net/tcp``, ``/proc/net/tcp6``) for every process of the evaluation (the evaluating
process, its recorder process and the web viewer's server)."""

from __future__ import annotations

import importlib.util
import ipaddress
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

pytestmark = [
    pytest.mark.skipif(importlib.util.find_spec("rerun") is None,
                       reason='rerun-sdk not installed: pip install "smartcar-gym[rerun]"'),
    pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="reads Linux's /proc/net"),
]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _tree(pid: int) -> list[int]:
    """``pid`` and every process it started, recursively."""
    parents: dict[int, list[int]] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                ppid = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            parents.setdefault(ppid, []).append(int(entry.name))
    found, todo = [pid], [pid]
    while todo:
        children = parents.get(todo.pop(), [])
        found += children
        todo += children
    return found


def _address(hex_address: str) -> tuple[str, int]:
    host, port = hex_address.split(":")
    raw = bytes.fromhex(host)
    # the kernel prints each 32-bit word in host order (little-endian here)
    raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
    return str(ipaddress.ip_address(raw)), int(port, 16)


def listening(pids: list[int]) -> set[tuple[str, int]]:
    """The TCP (address, port) pairs on which any of ``pids`` listens."""
    inodes = set()
    for pid in pids:
        try:
            for fd in Path(f"/proc/{pid}/fd").iterdir():
                target = os.readlink(fd)
                if target.startswith("socket:["):
                    inodes.add(target[8:-1])
        except OSError:  # gone, or not ours to read
            continue
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] == "0A" and fields[9] in inodes:  # 0A: LISTEN
                found.add(_address(fields[1]))
    return found


def _serve(tmp_path: Path, *extra: str, sigint: Any = signal.SIG_DFL
           ) -> tuple[subprocess.Popen, int, int, str]:
    """smartcar-eval --rerun-serve on free ports, once it says where it serves; started with
    SIGINT's disposition ``sigint`` (SIG_IGN: as a shell script's background job is)."""
    grpc, web = _free_port(), _free_port()
    log = tmp_path / "eval.err"
    with log.open("w") as err:  # the child keeps its own copy
        proc = subprocess.Popen(
            [sys.executable, "-m", "smartcar_gym.agents.cli_eval", "--random", "--episodes",
             "1", "--env", "SmartCarSim-v0", "--env-kwargs", "max_episode_steps=5",
             "--no-progress", "--rerun-serve", "--rerun-ports", str(grpc), str(web), *extra],
            stdout=subprocess.DEVNULL, stderr=err, start_new_session=True,
            preexec_fn=lambda: signal.signal(signal.SIGINT, sigint))
    deadline = time.monotonic() + 180
    while "Ctrl-C stops" not in log.read_text():
        if proc.poll() is not None or time.monotonic() > deadline:
            _stop(proc)
            pytest.fail(f"smartcar-eval --rerun-serve did not start: {log.read_text()}")
        time.sleep(0.2)
    return proc, grpc, web, log.read_text()


def _stop(proc: subprocess.Popen, sig: int = signal.SIGINT) -> None:
    if proc.poll() is None:
        os.killpg(proc.pid, sig)  # SIGINT: Ctrl-C, as a terminal sends it
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10)


def test_rerun_serve_listens_on_this_machine_only(tmp_path):
    proc, grpc, web, err = _serve(tmp_path)
    try:
        tree = _tree(proc.pid)
        sockets = listening(tree)
        assert {("127.0.0.1", grpc), ("127.0.0.1", web)} <= sockets, (sockets, err)
        beyond = {(host, port) for host, port in sockets
                  if not ipaddress.ip_address(host).is_loopback}
        assert not beyond, f"listening beyond loopback: {beyond}"
        assert f"Rerun web viewer: http://127.0.0.1:{web}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A" \
               f"{grpc}%2Fproxy" in err, err
        assert "warning" not in err
    finally:
        _stop(proc)
    assert proc.returncode == 0, err
    assert _alive(tree) == [], "processes outlived smartcar-eval"


@pytest.mark.parametrize(("sigint", "sig"), [(signal.SIG_IGN, signal.SIGINT),
                                             (signal.SIG_DFL, signal.SIGTERM)],
                         ids=["ctrl-c-where-sigint-was-ignored", "sigterm"])
def test_serving_stops_cleanly_on_ctrl_c_and_sigterm(tmp_path, sigint, sig):
    """Ctrl-C stops it also when started with SIGINT ignored (a script's background job,
    where Python leaves Ctrl-C ignored: it used to serve on, and a test suite run in the
    background hung here); SIGTERM stops it the same way: exit 0, nothing left running."""
    proc, _, _, err = _serve(tmp_path, sigint=sigint)
    tree = _tree(proc.pid)
    _stop(proc, sig)
    assert proc.returncode == 0, err
    assert _alive(tree) == [], "processes outlived smartcar-eval"


def _alive(pids: list[int], timeout_s: float = 15.0) -> list[str]:
    """The command lines of ``pids`` still running (zombies do not count) after waiting up to
    ``timeout_s`` for them to end."""
    deadline = time.monotonic() + timeout_s
    while True:
        alive = []
        for pid in pids:
            try:
                state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
                if state != "Z":
                    alive.append(Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " "))
            except OSError:
                pass
        if not alive or time.monotonic() > deadline:
            return alive
        time.sleep(0.1)


def test_rerun_bind_shares_both_servers_on_the_address_given(tmp_path):
    proc, grpc, web, err = _serve(tmp_path, "--rerun-bind", "0.0.0.0")
    try:
        sockets = listening(_tree(proc.pid))
        assert {("0.0.0.0", grpc), ("0.0.0.0", web)} <= sockets, (sockets, err)
        host = socket.gethostname()
        assert f"http://{host}:{web}/?url=rerun%2Bhttp%3A%2F%2F{host}%3A{grpc}" in err, err
        assert "warning: --rerun-bind 0.0.0.0: the web viewer and the episodes' gRPC server " \
               "are open to anyone who can reach this address" in err, err
    finally:
        _stop(proc)


@pytest.mark.parametrize(("argv", "message"), [
    (["--rerun-serve", "--rerun-bind", "example.org"],
     "--rerun-bind must be an IP address: 127.0.0.1 (this machine only, the default), "
     "0.0.0.0 (every IPv4 interface), :: (every interface) or one of this machine's "
     "addresses; got 'example.org'"),
    (["--rerun", "x.rrd", "--rerun-bind", "0.0.0.0"],
     "--rerun-bind: only --rerun-serve listens on an address"),
])
def test_a_bad_rerun_bind_is_one_line(argv, message, capsys):
    pytest.importorskip("stable_baselines3", reason="smartcar-eval needs the train extra")
    from smartcar_gym.agents import cli_eval

    with pytest.raises(SystemExit) as exit_:
        cli_eval.main(["--random", "--episodes", "1", *argv])
    assert exit_.value.code == 2
    assert capsys.readouterr().err.splitlines()[-1] == f"smartcar-eval: error: {message}"


def test_the_web_viewer_server_stops_with_its_sink():
    from smartcar_gym.viewers.rerun_log import RerunSink

    grpc, web = _free_port(), _free_port()
    sink = RerunSink(serve=True, grpc_port=grpc, web_port=web)
    server = sink.web_viewer
    assert server.running and ("127.0.0.1", web) in listening(_tree(server._process.pid))
    sink.close()
    sink.stop()
    assert not server.running and not Path(server._home).exists()  # no file left behind


def test_the_web_viewer_server_ends_with_a_killed_recorder():
    """A recorder process killed outright (SIGKILL: no clean-up runs) takes the web viewer's
    server with it (Linux: PR_SET_PDEATHSIG), so no server is left holding the port."""
    if not sys.platform.startswith("linux"):
        pytest.skip("PR_SET_PDEATHSIG is Linux's")
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    web = _free_port()
    sink = RerunProcessSink(serve=True, grpc_port=_free_port(), web_port=web)
    recorder = sink._process.pid
    servers = [pid for pid in _tree(recorder)
               if ("127.0.0.1", web) in listening([pid])]
    assert servers and servers[0] != recorder
    os.kill(recorder, signal.SIGKILL)
    try:
        assert _alive(servers) == []
    finally:
        sink.stop()
