"""What a viewer or a bag needs of an episode, read from a SmartCarEnv after reset and each step.

A ``Scene`` is what stays fixed during an episode (the car's shapes, the goal, the obstacles,
the URDF); a ``Frame`` is the state after one step (or after reset): simulated time, the true
pose and velocity, the controller's odometry, the wheel joint states, the command, the board's
PWM, the reward split into its terms, and the latest laser scan on SmartCarNav-v0. Both are
plain picklable data: ``CaptureWrapper`` puts them into ``info`` (``info["capture"]``), so they
come back from vector-env worker processes, and ``EpisodeCollector`` turns the frames of
interleaved sub-envs back into whole ``Episode`` objects, in episode order.

Capturing only reads the simulator: the episode is step for step what it is without it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from smartcar_gym.controller import Odometry
from smartcar_gym.envs.robots.smartcar import JointStates
from smartcar_gym.envs.sensors.scan import LaserScan
from smartcar_gym.envs.tasks.obstacles import Obstacle
from smartcar_gym.model.kinematics import link_frames, transform
from smartcar_gym.model.urdf import UrdfRobot

CAPTURE_KEY = "capture"  # the info key CaptureWrapper fills
_SHAPES: dict[str, tuple] = {}  # URDF text -> its visuals (VisualShape)


@dataclass(frozen=True)
class VisualShape:
    """A ``<visual>`` of the model: ``box`` (size x, y, z), ``cylinder`` (radius, length, along
    z) or ``sphere`` (radius,), placed by ``pose`` (4x4) in base_link."""

    link: str
    type: str
    size: tuple[float, ...]
    pose: np.ndarray


@dataclass(frozen=True)
class Scene:
    """What is fixed during one episode."""

    robot_name: str
    urdf: str
    shapes: tuple[VisualShape, ...]
    wheel_joints: tuple[str, ...]
    odom_frame: str
    base_frame: str
    goal: tuple[float, float]
    goal_tolerance_m: float
    arena_half_size_m: float
    obstacles: tuple[Obstacle, ...] = ()
    laser_mount: np.ndarray | None = None  # base_link -> laser (4x4); None without a laser
    laser_frame: str = "laser"


@dataclass
class Frame:
    """The state after one step (``reward`` 0 and no terms after reset); times in ns since
    the controller started (the episode's simulated clock)."""

    time_ns: int
    position: tuple[float, float, float]  # true base_link position in the world (m)
    orientation: tuple[float, float, float, float]  # (x, y, z, w)
    linear_velocity: tuple[float, float, float]  # world frame (m/s)
    angular_velocity: tuple[float, float, float]  # world frame (rad/s)
    odometry: Odometry
    joints: JointStates
    action: tuple[float, float]  # as the env used it (clipped to [-1, 1])
    command: tuple[float, float]  # cmd_vel sent: linear.x (m/s), angular.z (rad/s)
    pwm: tuple[int, int]
    reward: float
    reward_terms: dict[str, float]
    distance_m: float
    odom_error_m: float
    success: bool
    terminated: bool
    truncated: bool
    scan: LaserScan | None = None

    @property
    def time_s(self) -> float:
        return self.time_ns / 1e9


@dataclass
class Episode:
    """One whole episode: its scene and frames (``frames[0]``: after reset)."""

    index: int
    seed: int | None
    scene: Scene
    frames: list[Frame] = field(default_factory=list)

    @property
    def steps(self) -> int:
        return len(self.frames) - 1

    @property
    def success(self) -> bool:
        return bool(self.frames[-1].success)

    @property
    def episode_return(self) -> float:
        return float(sum(f.reward for f in self.frames))


def scene_of(env: gym.Env) -> Scene:
    """The ``Scene`` of a freshly reset SmartCarEnv (or a wrapper around one)."""
    base = _smartcar(env)
    model = base.robot_model
    odom = base.robot.odometry
    return Scene(
        robot_name=model.name, urdf=model.urdf, shapes=_shapes(model),
        wheel_joints=tuple(w.joint for w in base.robot.wheels),
        odom_frame=odom.frame_id, base_frame=odom.child_frame_id,
        goal=(float(base.goal[0]), float(base.goal[1])),
        goal_tolerance_m=float(base.task.goal_tolerance_m),
        arena_half_size_m=float(base.task.arena_half_size_m),
        obstacles=tuple(base.world.obstacles),
        laser_mount=None if getattr(base, "mount", None) is None else np.array(base.mount),
        laser_frame=base.laser_config.frame_id if hasattr(base, "laser_config") else "laser",
    )


def _shapes(model: Any) -> tuple[VisualShape, ...]:
    """The visuals of a robot model in base_link, worked out once per URDF (each episode of
    an env has the same)."""
    shapes = _SHAPES.get(model.urdf)
    if shapes is None:
        frames = link_frames(UrdfRobot(model.name, model.links, model.joints, model.base_link))
        shapes = tuple(
            VisualShape(link.name, visual.geometry.type, tuple(visual.geometry.size),
                        frames[link.name] @ transform(visual.origin))
            for link in model.links.values() if link.name in frames
            for visual in link.visuals if visual.geometry.type in ("box", "cylinder", "sphere")
        )
        if len(_SHAPES) >= 16:  # randomized models: keep a few
            _SHAPES.clear()
        _SHAPES[model.urdf] = shapes
    return shapes


class FrameReader:
    """Reads ``Frame`` objects from one env (the reward's terms as its task summed them)."""

    def __init__(self, env: gym.Env) -> None:
        self.base = _smartcar(env)

    def reset(self, info: dict[str, Any]) -> Frame:
        position, orientation = self.base.robot.body.link_pose()
        return self._frame(position, orientation, 0.0, 0.0, 0.0, {}, info, False, False)

    def step(self, action: Any, reward: float, terminated: bool, truncated: bool,
             info: dict[str, Any]) -> Frame:
        a0, a1 = min(max(float(action[0]), -1.0), 1.0), min(max(float(action[1]), -1.0), 1.0)
        position, orientation = self.base.robot.body.link_pose()
        return self._frame(position, orientation, a0, a1, float(reward), self._terms(), info,
                           bool(terminated), bool(truncated))

    def _terms(self) -> dict[str, float]:
        """The reward's terms as the task summed them (``Task.terms``: their sum is the
        reward)."""
        return {name: float(np.broadcast_to(value, (1,))[0])
                for name, value in self.base.task.terms.items()}

    def _frame(self, position: Sequence[float], orientation: Sequence[float], a0: float,
               a1: float, reward: float, terms: dict[str, float], info: dict[str, Any],
               terminated: bool, truncated: bool) -> Frame:
        base = self.base
        robot = base.robot
        linear, angular = robot.body.velocity()
        laser = getattr(base, "laser", None)
        return Frame(
            base.sim.now_ns, position, orientation, linear, angular, robot.odometry,
            robot.joint_states(), (a0, a1), (a0 * base.max_linear, a1 * base.max_angular),
            robot.base.board.pwm, reward, terms, float(info["distance"]),
            float(info["odom_error"]), bool(info["is_success"]), terminated, truncated,
            None if laser is None else laser.latest,
        )


def _smartcar(env: gym.Env) -> Any:
    base = env.unwrapped
    if not all(hasattr(base, name) for name in ("robot", "sim", "goal", "task")):
        raise ValueError(f"recording needs a SmartCarEnv (SmartCar-v0, SmartCarSim-v0, "
                         f"SmartCarNav-v0, SmartCarGoal-v0); got a {type(base).__name__}")
    return base


class CaptureWrapper(gym.Wrapper):
    """Adds ``info["capture"]``: ``(scene, frame)`` after reset, the ``Frame`` after a step.

    Put it outside the ``TimeLimit`` (``gym.make``'s env) so that truncation is seen.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self._reader = FrameReader(env)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        info[CAPTURE_KEY] = (scene_of(self.env), self._reader.reset(info))
        return obs, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        info[CAPTURE_KEY] = self._reader.step(action, reward, terminated, truncated, info)
        return obs, reward, terminated, truncated, info


class EpisodeCollector:
    """Gathers the captured frames of the sub-envs of a vector loop and hands each finished
    episode to ``write`` in episode order (an episode that ends early waits for the ones
    before it)."""

    def __init__(self, write: Callable[[Episode], None] | Sequence[Callable[[Episode], None]],
                 first_index: int = 0) -> None:
        self._writers = [write] if callable(write) else list(write)
        self._open: dict[int, Episode] = {}  # slot -> episode being run
        self._done: dict[int, Episode] = {}  # index -> finished, waiting for earlier ones
        self._next = first_index

    def begin(self, slot: int, index: int, seed: int | None, captured: Any) -> None:
        scene, frame = captured
        self._open[slot] = Episode(index, seed, scene, [frame])

    def add(self, slot: int, frame: Frame) -> None:
        episode = self._open[slot]
        episode.frames.append(frame)
        if frame.terminated or frame.truncated:
            del self._open[slot]
            self._done[episode.index] = episode
            while self._next in self._done:
                finished = self._done.pop(self._next)
                for write in self._writers:
                    write(finished)
                self._next += 1
