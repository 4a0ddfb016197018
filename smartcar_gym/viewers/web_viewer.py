"""Rerun's web viewer served on one address: this machine only (127.0.0.1) unless asked.

``rerun.serve_web_viewer`` has no bind address: its HTTP server listens on every interface
(0.0.0.0). The ``rerun`` command of the same ``rerun-sdk`` wheel (``rerun_cli``) has one
(``--bind``): ``WebViewerServer`` runs it as ``rerun --serve-web --bind ADDRESS
--web-viewer-port PORT URL``, which serves only the viewer's files (HTML, JavaScript,
WebAssembly) pointed at the gRPC server at ``URL`` (no gRPC server of its own), waits for its
"Hosting a web-viewer" line, and ends it with ``stop`` or when this process ends (at exit, and
on Linux through ``PR_SET_PDEATHSIG`` when the thread that started it dies).

The command runs with Rerun's usage analytics off and its configuration in a temporary folder:
nothing is sent and nothing is left in the user's home (``~/.config/rerun``).
"""

from __future__ import annotations

import atexit
import ctypes
import ipaddress
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
from pathlib import Path
from urllib.parse import quote

LOOPBACK = "127.0.0.1"
START_TIMEOUT_S = 60.0
_READY = re.compile(r"Hosting a web-viewer at http://\S+?:(\d+)")
_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def check_bind(address: str, name: str = "bind") -> str:
    """``address`` if it is an IP address (the form ``rerun --bind`` takes); one line if not."""
    try:
        return str(ipaddress.ip_address(str(address).strip("[]")))
    except ValueError:
        raise ValueError(f"{name} must be an IP address: 127.0.0.1 (this machine only, the "
                         f"default), 0.0.0.0 (every IPv4 interface), :: (every interface) or "
                         f"one of this machine's addresses; got {address!r}") from None


def is_loopback(address: str) -> bool:
    """Whether ``address`` is reachable from this machine only."""
    return ipaddress.ip_address(address).is_loopback


def url_host(bind: str) -> str:
    """The host part of a URL for a server bound to ``bind``: the address itself, or for a
    wildcard (0.0.0.0, ::) this machine's name; IPv6 in brackets."""
    ip = ipaddress.ip_address(bind)
    if ip.is_unspecified:
        return socket.gethostname()
    return f"[{ip}]" if ip.version == 6 else str(ip)


def grpc_url(bind: str, port: int) -> str:
    """The address of Rerun's gRPC server (``GrpcServerSink``) bound to ``bind``:``port``."""
    return f"rerun+http://{url_host(bind)}:{port}/proxy"


def web_viewer_url(grpc: str, web_port: int, bind: str = LOOPBACK) -> str:
    """The web viewer's address, connected to the gRPC server at ``grpc``."""
    return f"http://{url_host(bind)}:{web_port}/?url={quote(grpc, safe='')}"


def cli_path() -> Path:
    """The ``rerun`` executable of the installed rerun-sdk (as ``python -m rerun_cli`` finds it;
    ``RERUN_CLI_PATH`` overrides)."""
    if "RERUN_CLI_PATH" in os.environ:
        return Path(os.environ["RERUN_CLI_PATH"])
    import rerun_cli

    folder = Path(rerun_cli.__file__).parent
    bundled = folder / "Rerun.app" / "Contents" / "MacOS" / "Rerun"
    if sys.platform == "darwin" and bundled.exists():
        return bundled
    return folder / ("rerun.exe" if sys.platform.startswith("win") else "rerun")


def _die_with_parent() -> None:  # pragma: no cover (runs in the child, before exec)
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


class WebViewerServer:
    """Rerun's web viewer on ``bind``:``port`` (0: a free port), connected to ``connect_to``.

    Raises ``RuntimeError`` with the command's own line when it cannot serve (a port in use:
    "... Address already in use ..."), ``FileNotFoundError`` without the ``rerun`` command.
    """

    def __init__(self, port: int, connect_to: str, bind: str = LOOPBACK,
                 timeout_s: float = START_TIMEOUT_S) -> None:
        self.bind = check_bind(bind)
        self.connect_to = connect_to
        self._home = tempfile.mkdtemp(prefix="smartcar-rerun-web-")
        config = Path(self._home) / "rerun"
        config.mkdir()
        (config / "analytics.json").write_text(json.dumps({
            "analytics_enabled": False, "analytics_id": "0" * 32, "metadata": {},
            "config_file_path": str(config / "analytics.json"),
            "data_dir_path": str(config / "analytics")}))
        env = {**os.environ, "XDG_CONFIG_HOME": self._home, "XDG_DATA_HOME": self._home,
               "NO_COLOR": "1", "RUST_LOG": "info"}
        command = [str(cli_path()), "--serve-web", "--bind", self.bind,
                   "--web-viewer-port", str(int(port)), connect_to]
        linux = sys.platform.startswith("linux")
        try:
            self._process = subprocess.Popen(
                command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE, text=True, errors="replace", env=env,
                preexec_fn=_die_with_parent if linux else None)  # noqa: PLW1509
        except OSError:
            shutil.rmtree(self._home, ignore_errors=True)
            raise
        atexit.register(self.stop)
        self._lines: list[str] = []
        try:
            self.port = self._wait_ready(timeout_s)
        except BaseException:
            self.stop()
            raise
        self._drainer = threading.Thread(target=self._drain, name="rerun-web-viewer-log",
                                         daemon=True)
        self._drainer.start()
        self.url = web_viewer_url(connect_to, self.port, self.bind)

    def _wait_ready(self, timeout_s: float) -> int:
        """The port from the command's "Hosting a web-viewer at" line; its error if it ends."""
        found: list[int] = []

        def read() -> None:
            for raw in self._process.stderr:
                line = _ANSI.sub("", raw).strip()
                self._lines.append(line)
                match = _READY.search(line)
                if match:
                    found.append(int(match.group(1)))
                    return

        self._reader = reader = threading.Thread(target=read, daemon=True)
        reader.start()
        reader.join(timeout_s)
        if found:
            return found[0]
        if reader.is_alive():
            raise TimeoutError(f"Rerun's web viewer did not start on {self.bind} in "
                               f"{timeout_s:g} s")
        errors = [line for line in self._lines if "error" in line.lower()] or self._lines[-1:]
        raise RuntimeError(f"Rerun's web viewer cannot serve on {self.bind}: "
                           f"{errors[-1] if errors else 'rerun exited'} (the rerun command "
                           f"ended with exit code {self._process.wait()})")

    def _drain(self) -> None:
        """Read what the command says after its start, so that it never blocks on its pipe."""
        try:
            for _ in self._process.stderr:
                pass
        except (OSError, ValueError):
            pass

    @property
    def running(self) -> bool:
        return self._process.poll() is None

    def stop(self) -> None:
        """End the server (idempotent)."""
        process = getattr(self, "_process", None)
        if process is not None and process.poll() is None:
            process.terminate()
            try:
                process.wait(10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait(10)
        readers = [t for t in (getattr(self, "_reader", None), getattr(self, "_drainer", None))
                   if t is not None]
        for reader in readers:
            reader.join(1.0)  # at the pipe's end once the command has ended
        if process is not None and not any(reader.is_alive() for reader in readers):
            process.stderr.close()  # also after a failed start: no unclosed pipe left
        shutil.rmtree(self._home, ignore_errors=True)
        atexit.unregister(self.stop)

    def __enter__(self) -> WebViewerServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

