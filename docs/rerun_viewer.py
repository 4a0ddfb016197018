"""Makes docs/rerun_viewer.png: Rerun's web viewer, served by ``smartcar-eval --rerun-serve``,
showing the shipped SmartCarNav-v0 policy's first episode, in headless Chromium.

Needs the rerun extra, Debian's chromium, and smartcar-eval on PATH (the virtualenv active).
Usage: python docs/rerun_viewer.py [OUT.png]
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

from smartcar_gym.viewers.chromium import color_pixels, screenshot
from smartcar_gym.viewers.rerun_log import GOAL_COLOR, TRUTH_COLOR


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main() -> None:
    out = Path(sys.argv[1] if len(sys.argv) > 1 else Path(__file__).with_name(
        "rerun_viewer.png"))
    grpc, web = free_port(), free_port()
    command = ["smartcar-eval", "--pretrained", "nav", "--episodes", "1", "--no-progress",
               "--rerun-serve", "--rerun-ports", str(grpc), str(web)]
    process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True)
    try:
        url = None
        for line in process.stderr:
            sys.stderr.write(line)
            if "serving the episodes at " in line:
                url = line.split("serving the episodes at ")[1].split(";")[0]
                break
        if url is None:
            raise SystemExit("smartcar-eval stopped before serving")
        time.sleep(1.0)

        def ready(image):  # the goal (red) and the true path (green) are drawn
            return (color_pixels(image, GOAL_COLOR) > 100
                    and color_pixels(image, TRUTH_COLOR) > 50)

        screenshot(url, out, width=1400, height=800, ready=ready, settle_s=3.0, timeout_s=180)
        print(f"wrote {out}")
    finally:
        process.send_signal(signal.SIGINT)
        process.wait(timeout=30)


if __name__ == "__main__":
    main()
