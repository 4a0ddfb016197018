"""``smartcar-eval``'s outputs: the files it is asked to write, checked before any episode
runs (``check_outputs``), and the recorders the episodes stream to (``--rerun``,
``--rerun-serve``, a ROS 2 ``--bag``: ``open_recorders``, ``close_recorders``,
``serve_until_interrupted``)."""

from __future__ import annotations

import argparse
import contextlib
import sys
from typing import Any

from smartcar_gym.agents.atomic_files import output_path_error

__all__ = ["check_outputs", "check_rerun_bind", "close_recorders", "count", "open_recorders",
           "serve_until_interrupted"]


def open_recorders(args: argparse.Namespace, stack: contextlib.ExitStack) -> list[Any]:
    """The sinks the evaluated episodes go to (``--rerun``, ``--rerun-serve``, a ros2
    ``--bag``); an error leaves no half-written file."""
    recorders: list[Any] = []
    if args.rerun is not None or args.rerun_serve:
        from smartcar_gym.viewers.rerun_process import RerunProcessSink

        grpc_port, web_port = args.rerun_ports  # rerun itself is the recorder process's
        sink = RerunProcessSink(args.rerun, serve=args.rerun_serve, grpc_port=grpc_port,
                                web_port=web_port, bind=args.rerun_bind)
        if sink.web_url:
            print(f"smartcar-eval: Rerun web viewer: {sink.web_url}", file=sys.stderr)
        recorders.append(sink)
    if args.bag is not None and args.bag_format == "ros2":
        from smartcar_gym.bags.ros2 import Ros2BagSink

        recorders.append(Ros2BagSink(args.bag, storage=args.bag_storage))

    def discard(kind: Any, error: Any, trace: Any) -> None:
        if error is not None:
            for recorder in recorders:
                recorder.discard()

    stack.push(discard)
    return recorders


def close_recorders(recorders: list[Any]) -> dict[str, Any]:
    """Finish the recorders' files; what they wrote, for the summary table."""
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    written: dict[str, Any] = {}
    for recorder in recorders:
        recorder.close()
        if isinstance(recorder, RerunProcessSink):
            if recorder.path is not None:
                written[f"rerun ({count(recorder.episodes, 'episode')})"] = recorder.path
        else:
            written[f"ros2 bag ({recorder.count} messages)"] = recorder.path
    return written


def serve_until_interrupted(recorders: list[Any]) -> None:
    """Keep the web viewer (the recorder process) up until Ctrl-C or SIGTERM."""
    from smartcar_gym.viewers.rerun_process import RerunProcessSink

    sink = next(r for r in recorders if isinstance(r, RerunProcessSink))
    print(f"smartcar-eval: serving the episodes at {sink.web_url}; Ctrl-C stops",
          file=sys.stderr)
    sink.serve_until_interrupted()


def check_outputs(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse (``parser.error``) output files that could not be written, before evaluating."""
    if args.video is not None and args.video.suffix.lower() not in (".gif", ".mp4"):
        parser.error(f"--video: the file must end in .gif or .mp4, got {str(args.video)!r}")
    if args.plot is not None and args.plot.suffix:
        from matplotlib.backend_bases import FigureCanvasBase

        formats = FigureCanvasBase.get_supported_filetypes()
        if args.plot.suffix[1:].lower() not in formats:
            parser.error(f"--plot: cannot write {args.plot.suffix} images; use .png, .svg or "
                         ".pdf")
    if args.bag is not None and args.bag_format == "ros1":
        from smartcar_gym.bags.ros1 import SUFFIXES, missing_library

        if args.bag.suffix not in SUFFIXES:
            parser.error(f"--bag: the file must end in .bag or .mcap, got {str(args.bag)!r}")
        if missing_library():
            parser.error(f"--bag: {missing_library()}")
    if args.bag is not None and args.bag_format == "ros2":
        from smartcar_gym.bags.ros2 import missing_library

        if missing_library():
            parser.error(f"--bag: {missing_library()}")
        if args.bag.exists():
            parser.error(f"--bag: {args.bag} exists; a ROS 2 bag is a new folder (remove it "
                         "or pick another name)")
    if args.rerun is not None or args.rerun_serve:
        from smartcar_gym.viewers import missing_rerun

        option = "--rerun" if args.rerun is not None else "--rerun-serve"
        if missing_rerun():
            parser.error(f"{option}: {missing_rerun()}")
        if args.rerun is not None and args.rerun.suffix != ".rrd":
            parser.error(f"--rerun: the file must end in .rrd, got {str(args.rerun)!r}")
    check_rerun_bind(parser, args)
    for option, path in (("--json", args.json), ("--plot", args.plot), ("--video", args.video),
                         ("--bag", args.bag), ("--rerun", args.rerun)):
        problem = None if path is None else output_path_error(path)
        if problem:
            parser.error(f"{option}: {problem}")


def count(n: int, noun: str) -> str:
    """``1 episode``, ``2 episodes``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def check_rerun_bind(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """``--rerun-bind``: an IP address, with ``--rerun-serve``; a warning beyond loopback."""
    from smartcar_gym.viewers.web_viewer import check_bind, is_loopback

    if args.rerun_bind == "127.0.0.1":
        return
    if not args.rerun_serve:
        parser.error("--rerun-bind: only --rerun-serve listens on an address")
    try:
        args.rerun_bind = check_bind(args.rerun_bind, "--rerun-bind")
    except ValueError as err:
        parser.error(str(err))
    if not is_loopback(args.rerun_bind):
        print(f"smartcar-eval: warning: --rerun-bind {args.rerun_bind}: the web viewer and the "
              "episodes' gRPC server are open to anyone who can reach this address (no "
              "password, no encryption)", file=sys.stderr)
