"""Episodes as a Rerun recording: to an ``.rrd`` file, to Rerun's web viewer live, or both.

One recording holds every episode, each under entities of its own (``episode_007``), on one
timeline, ``sim_time``: simulated seconds since the episode's controller started, so episodes
play side by side. Entity tree (REP 103 axes: x forward, z up; metres, radians)::

    world/episode_NNN/goal                 goal point and its tolerance circle (static)
    world/episode_NNN/obstacles/{boxes,cylinders}                             (static)
    world/episode_NNN/path/truth           the true base_link path             (static)
    world/episode_NNN/car                  true pose of base_link, per step
    world/episode_NNN/car/shapes/{boxes,cylinders,spheres}   the URDF's visuals (static)
    world/episode_NNN/car/laser/scan       the laser's points, laser frame (SmartCarNav-v0)
    world/episode_NNN/odom                 the odometry frame: the start pose (static)
    world/episode_NNN/odom/base_link       the controller's odometry pose, per step
    world/episode_NNN/odom/path            the odometry path                   (static)
    wheel_speed/episode_NNN                wheel joint velocities (rad/s), one series a wheel
    command/episode_NNN                    cmd_vel linear.x (m/s), angular.z (rad/s)
    pwm/episode_NNN                        the board's PWM, left and right (-255..255)
    reward/episode_NNN                     the reward's terms and their total
    distance/episode_NNN, odom_error/episode_NNN, success/episode_NNN
    robot_description                      the URDF text (static)

Needs ``rerun-sdk`` (the ``rerun`` extra). Episodes are sent whole, as columns, when they
end: recording costs little next to simulating them.
"""

from __future__ import annotations

import ipaddress
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

from smartcar_gym.envs.robots.smartcar import pose_from
from smartcar_gym.envs.world import OBSTACLE_HEIGHT_M
from smartcar_gym.model.kinematics import matrix_quaternion
from smartcar_gym.viewers.capture import Episode, Scene
from smartcar_gym.viewers.packing import Packet, Table, pack
from smartcar_gym.viewers.web_viewer import LOOPBACK, WebViewerServer, check_bind, grpc_url

APPLICATION_ID = "smartcar_gym"
TIMELINE = "sim_time"
GRPC_PORT = 9876  # Rerun's defaults
WEB_PORT = 9090
TRUTH_COLOR = (40, 170, 80)
ODOM_COLOR = (240, 140, 20)
GOAL_COLOR = (220, 40, 40)
SCAN_COLOR = (230, 30, 30)
OBSTACLE_COLOR = (140, 140, 150)
SHAPE_COLORS = {"box": (60, 110, 200), "cylinder": (40, 40, 40), "sphere": (90, 90, 90)}
_CAR_SHAPES: dict[tuple, list[tuple[str, Any]]] = {}  # the car's archetypes, by its visuals
_SERIES_LINES: dict[tuple[str, ...], Any] = {}  # series names: the same for every episode
_UNCHANGING: dict[str, Any] = {}  # the odometry arrow, the scan's colour and radius
_ARRAYS: dict[tuple, Any] = {}  # colours and radii as arrow arrays


def skip_pandas_probe() -> None:
    """Spare a process that has not imported pandas its import (a third of what starting a
    recording costs): pyarrow, under rerun-sdk, imports pandas on its first array built from
    a list only to ask whether that list is a pandas object, which it cannot be then. Here
    that first probe finds no pandas; pyarrow's own pandas features (``to_pandas``) still
    import it when called. For a process of its own, like ``smartcar-eval``: pyarrow stops
    recognising pandas objects that are made later in the same process.
    """
    if "pandas" in sys.modules:
        return
    import pyarrow as pa

    class _NoPandas:
        def find_spec(self, name: str, path: Any = None, target: Any = None) -> None:
            if name == "pandas":
                raise ModuleNotFoundError("pandas is not looked for here", name=name)

    finder = _NoPandas()
    sys.meta_path.insert(0, finder)
    try:
        pa.array([0])  # pyarrow looks for pandas once, on this first list
    finally:
        sys.meta_path.remove(finder)


def blueprint() -> Any:
    """The viewer's layout: the world in 3D beside the time series."""
    import rerun.blueprint as rrb

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/world", name="world (true pose, odometry, goal, scan)"),
            rrb.Vertical(
                rrb.TimeSeriesView(origin="/wheel_speed", name="wheel speeds (rad/s)"),
                rrb.TimeSeriesView(origin="/command", name="cmd_vel (m/s, rad/s)"),
                rrb.TimeSeriesView(origin="/pwm", name="PWM"),
                rrb.TimeSeriesView(origin="/reward", name="reward terms"),
                rrb.TimeSeriesView(origin="/distance", name="distance to goal (m)"),
            ),
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


class RerunSink:
    """Writes ``Episode`` objects to a Rerun recording.

    Args:
        path: an ``.rrd`` file, written whole when ``close`` is called.
        serve: host a gRPC server (``grpc_port``) and Rerun's web viewer (``web_port``), both
            from the ``rerun-sdk`` package (no internet); ``web_url`` is where to look.
        bind: the IP address both listen on: 127.0.0.1 (this machine only, the default), or
            an address of this machine's network (0.0.0.0: every IPv4 interface), for anyone
            who can reach it (docs/viewers.md says what is then exposed).
        recording: a ``rerun.RecordingStream`` of your own instead (then ``path`` and
            ``serve`` must be left out): the episodes go to wherever it sends its data.
    """

    def __init__(self, path: str | os.PathLike | None = None, *, serve: bool = False,
                 grpc_port: int = GRPC_PORT, web_port: int = WEB_PORT,
                 recording: Any = None, recording_id: str | None = None,
                 bind: str = LOOPBACK) -> None:
        import rerun as rr

        self.path = None if path is None else Path(path)
        self.web_url: str | None = None
        self.web_viewer: WebViewerServer | None = None
        bind = check_bind(bind)
        self.episodes = 0
        self._described = False
        if recording is not None:
            if path is not None or serve:
                raise ValueError("pass a recording or path/serve, not both")
            self.rec = recording
            self._partial = None
        else:
            if path is None and not serve:
                raise ValueError("a Rerun recording needs a path (.rrd), serve=True or both")
            if self.path is not None and self.path.suffix != ".rrd":
                raise ValueError(f"Rerun recordings end in .rrd, got {self.path.name!r}")
            hosted = hasattr(rr, "GrpcServerSink")  # rerun-sdk 0.24 serves with serve_grpc
            if serve and path is not None and not hosted:
                raise ValueError(f"rerun-sdk {rr.__version__} cannot write a file and serve at "
                                 "once; upgrade it (pip install -U rerun-sdk) or do one")
            if serve and not hosted and ipaddress.ip_address(bind) != ipaddress.ip_address(
                    "0.0.0.0"):
                raise ValueError(f"rerun-sdk {rr.__version__} serves gRPC on every interface "
                                 f"only, not on {bind}; upgrade it (pip install -U rerun-sdk)")
            self.rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
            self._partial = None
            sinks = []
            if self.path is not None:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                self._partial = self.path.with_name(f".{self.path.stem}.partial.rrd")
                sinks.append(rr.FileSink(str(self._partial)))
            if serve and hosted:
                sinks.append(rr.GrpcServerSink(bind_ip=bind, port=grpc_port))
                url = grpc_url(bind, grpc_port)
            if sinks:
                self.rec.set_sinks(*sinks, default_blueprint=blueprint())
            else:  # serving with rerun-sdk 0.24
                self.rec.serve_grpc(grpc_port=grpc_port, default_blueprint=blueprint())
                url = grpc_url(bind, grpc_port)
            if serve:  # not rr.serve_web_viewer: it listens on every interface (0.0.0.0)
                self.web_viewer = WebViewerServer(web_port, url, bind)
                self.web_url = self.web_viewer.url
        self.rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)

    def __call__(self, episode: Episode) -> None:
        self.write(episode)

    def write(self, episode: Episode) -> None:
        """Send one whole episode."""
        self.send(pack(episode, urdf=not self._described))

    def send(self, packet: Packet) -> None:
        """Send one whole episode, packed (``pack``)."""
        import rerun as rr

        rec, name, scene, table = self.rec, packet.entity, packet.scene, packet.table
        if not self._described:
            rec.log("robot_description", rr.TextDocument(scene.urdf, media_type="text/plain"),
                    static=True)
            self._described = True
        world = f"world/{name}"
        _log_scene(rec, world, scene)
        times = rr.TimeColumn(TIMELINE, duration=table.time_ns / 1e9)
        truth = table.position
        rec.log(f"{world}/path/truth", rr.LineStrips3D([truth], colors=_color(TRUTH_COLOR),
                                                       radii=_radius(0.01)), static=True)
        rec.send_columns(f"{world}/car", indexes=[times], columns=rr.Transform3D.columns(
            translation=truth, quaternion=table.orientation))
        start = table.position[0].tolist()
        yaw0 = pose_from(start, table.orientation[0].tolist()).yaw
        rec.log(f"{world}/odom", rr.Transform3D(
            translation=(start[0], start[1], 0.0),
            quaternion=(0.0, 0.0, np.sin(yaw0 / 2), np.cos(yaw0 / 2))), static=True)
        odom = table.odometry
        odom_xyz = np.column_stack([odom[:, 0], odom[:, 1], np.full(len(odom), truth[0, 2])])
        rec.log(f"{world}/odom/path", rr.LineStrips3D([odom_xyz], colors=_color(ODOM_COLOR),
                                                      radii=_radius(0.01)), static=True)
        rec.log(f"{world}/odom/base_link", _unchanging("odom_arrow"), static=True)
        half = odom[:, 2] / 2
        rec.send_columns(f"{world}/odom/base_link", indexes=[times],
                         columns=rr.Transform3D.columns(
                             translation=odom_xyz,
                             quaternion=np.column_stack([np.zeros_like(half),
                                                         np.zeros_like(half), np.sin(half),
                                                         np.cos(half)])))
        if packet.scans is not None:
            _log_scans(rec, f"{world}/car/laser", scene, packet.scans, times)
        _log_series(rec, name, scene, table, times)
        self.episodes += 1

    def close(self) -> None:
        """Flush; the ``.rrd`` file appears at its path now, complete."""
        self.rec.flush()
        if self._partial is not None:
            self.rec.disconnect()
            os.replace(self._partial, self.path)
            self._partial = None

    def discard(self) -> None:
        """Stop without leaving a file (after an error)."""
        if self._partial is not None:
            self.rec.disconnect()
            self._partial.unlink(missing_ok=True)
            self._partial = None

    def stop(self) -> None:
        """Stop serving the web viewer (it also stops when this process ends)."""
        if self.web_viewer is not None:
            self.web_viewer.stop()


def _log_series(rec: Any, name: str, scene: Scene, table: Table, times: Any) -> None:
    """The time series of one episode (wheel speeds, command, PWM, reward terms, ...)."""
    import rerun as rr

    def series(path: str, values: np.ndarray, names: list[str]) -> None:
        lines = _SERIES_LINES.get(tuple(names))
        if lines is None:
            lines = _SERIES_LINES[tuple(names)] = rr.SeriesLines(names=names)
        rec.log(path, lines, static=True)
        rec.send_columns(path, indexes=[times], columns=rr.Scalars.columns(scalars=values))

    series(f"wheel_speed/{name}", table.wheel_speed, list(scene.wheel_joints))
    series(f"command/{name}", table.command, ["linear.x (m/s)", "angular.z (rad/s)"])
    series(f"pwm/{name}", table.pwm, ["left", "right"])
    series(f"reward/{name}", table.rewards, table.reward_names)
    series(f"distance/{name}", table.distance, ["distance"])
    series(f"odom_error/{name}", table.odom_error, ["odometry error (m)"])
    series(f"success/{name}", table.success, ["success"])


def _color(rgb: tuple[int, int, int]) -> Any:
    """One colour as Rerun's arrow array, converted once (converting costs more than a
    line strip of a whole episode)."""
    cached = _ARRAYS.get(("color", rgb))
    if cached is None:
        import rerun as rr

        cached = _ARRAYS[("color", rgb)] = rr.components.ColorBatch([rgb]).as_arrow_array()
    return cached


def _radius(radius: float) -> Any:
    """One radius as Rerun's arrow array, converted once."""
    cached = _ARRAYS.get(("radius", radius))
    if cached is None:
        import rerun as rr

        cached = _ARRAYS[("radius", radius)] = rr.components.RadiusBatch(radius).as_arrow_array()
    return cached


def _unchanging(kind: str) -> Any:
    """An archetype that every episode logs the same (built once)."""
    cached = _UNCHANGING.get(kind)
    if cached is None:
        import rerun as rr

        if kind == "odom_arrow":
            cached = rr.Arrows3D(vectors=[(0.15, 0.0, 0.0)], colors=[ODOM_COLOR], radii=0.008)
        else:  # "scan_style": static positions would hide the per-step ones
            cached = rr.Points3D.from_fields(colors=[SCAN_COLOR], radii=0.02)
        _UNCHANGING[kind] = cached
    return cached


def _log_scene(rec: Any, world: str, scene: Scene) -> None:
    """The goal, the obstacles and the car's shapes (static)."""
    import rerun as rr

    gx, gy = scene.goal
    rec.log(f"{world}/goal", rr.Points3D([(gx, gy, 0.0)], colors=_color(GOAL_COLOR),
                                         radii=_radius(0.03), labels=["goal"]), static=True)
    angle = np.linspace(0.0, 2 * np.pi, 49)
    circle = np.column_stack([gx + scene.goal_tolerance_m * np.cos(angle),
                              gy + scene.goal_tolerance_m * np.sin(angle), np.zeros_like(angle)])
    rec.log(f"{world}/goal/tolerance", rr.LineStrips3D([circle], colors=_color(GOAL_COLOR),
                                                       radii=_radius(0.004)), static=True)
    boxes = [o for o in scene.obstacles if o.shape == "box"]
    cylinders = [o for o in scene.obstacles if o.shape == "cylinder"]
    height = OBSTACLE_HEIGHT_M
    if boxes:
        rec.log(f"{world}/obstacles/boxes", rr.Boxes3D(
            half_sizes=[(o.size[0] / 2, o.size[1] / 2, height / 2) for o in boxes],
            centers=[(*o.position, height / 2) for o in boxes],
            quaternions=[(0.0, 0.0, np.sin(o.yaw / 2), np.cos(o.yaw / 2)) for o in boxes],
            colors=_color(OBSTACLE_COLOR), fill_mode="solid"), static=True)
    if cylinders:
        rec.log(f"{world}/obstacles/cylinders", rr.Cylinders3D(
            lengths=[height] * len(cylinders), radii=[o.size[0] / 2 for o in cylinders],
            centers=[(*o.position, height / 2) for o in cylinders],
            colors=_color(OBSTACLE_COLOR), fill_mode="solid"), static=True)
    for kind, archetype in _car_shapes(scene.shapes):
        rec.log(f"{world}/car/shapes/{kind}", archetype, static=True)


def _car_shapes(shapes: tuple) -> list[tuple[str, Any]]:
    """The car's visuals as one archetype per kind (built once per model: episodes share it)."""
    key = tuple((s.link, s.type, s.size, s.pose.tobytes()) for s in shapes)
    cached = _CAR_SHAPES.get(key)
    if cached is not None:
        return cached
    import rerun as rr

    built = []
    for kind in ("box", "cylinder", "sphere"):
        chosen = [s for s in shapes if s.type == kind]
        if not chosen:
            continue
        centers = [s.pose[:3, 3] for s in chosen]
        quaternions = [matrix_quaternion(s.pose[:3, :3]) for s in chosen]
        colors = [SHAPE_COLORS[kind]] * len(chosen)
        if kind == "box":
            archetype = rr.Boxes3D(sizes=[s.size for s in chosen], centers=centers,
                                   quaternions=quaternions, colors=colors, fill_mode="solid")
        elif kind == "cylinder":
            archetype = rr.Cylinders3D(radii=[s.size[0] for s in chosen],
                                       lengths=[s.size[1] for s in chosen], centers=centers,
                                       quaternions=quaternions, colors=colors,
                                       fill_mode="solid")
        else:
            archetype = rr.Ellipsoids3D(half_sizes=[(s.size[0],) * 3 for s in chosen],
                                        centers=centers, colors=colors, fill_mode="solid")
        built.append((f"{kind}es" if kind == "box" else f"{kind}s", archetype))
    _CAR_SHAPES[key] = built
    return built


def _log_scans(rec: Any, laser: str, scene: Scene, scans: tuple[np.ndarray, list[int]],
               times: Any) -> None:
    """Each frame's latest scan as points in the laser frame (finite ranges only)."""
    import rerun as rr

    mount = scene.laser_mount
    rec.log(laser, rr.Transform3D(translation=mount[:3, 3], mat3x3=mount[:3, :3]), static=True)
    positions, lengths = scans
    rec.log(f"{laser}/scan", _unchanging("scan_style"), static=True)
    rec.send_columns(f"{laser}/scan", indexes=[times],
                     columns=rr.Points3D.columns(positions=positions).partition(lengths))
