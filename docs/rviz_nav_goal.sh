#!/usr/bin/env bash
# Makes docs/rviz_nav_goal.png: rviz (the tutorial's urdf.rviz) on a virtual display while the
# shipped policy drives the simulated smartcar to a goal set with rviz's 2D Nav Goal tool.
# Needs Debian's ROS (docs/ros.md), rviz, xvfb, xdotool and imagemagick (import), and
# smartcar-ros on PATH (the virtualenv active). Usage: bash docs/rviz_nav_goal.sh [OUT.png]
set -euo pipefail
out="$(realpath "${1:-docs/rviz_nav_goal.png}")"
work="$(mktemp -d)"
port="$(python -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')"
export ROS_MASTER_URI="http://127.0.0.1:$port" ROS_IP=127.0.0.1 ROS_HOME="$work"
export ROS_PACKAGE_PATH="$(smartcar-ros package)" LIBGL_ALWAYS_SOFTWARE=1
pids=()
descendants() {
  local child
  for child in $(ps -o pid= --ppid "$1"); do echo "$child"; descendants "$child"; done
}
cleanup() {  # SIGINT, up to 15 s to shut down, then SIGKILL for all that the script started
  local all=() pid alive
  for pid in "${pids[@]}"; do all+=("$pid" $(descendants "$pid")); done
  for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  for _ in $(seq 30); do
    alive=0
    for pid in "${all[@]}"; do kill -0 "$pid" 2>/dev/null && alive=1; done
    [ "$alive" = 0 ] && break
    sleep 0.5
  done
  for pid in "${all[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
# large enough for urdf.rviz's window geometry (972x696 at 772,332)
Xvfb -displayfd 3 -screen 0 1760x1040x24 -nolisten tcp 3>"$work/display" &
pids+=($!)
until [ -s "$work/display" ]; do sleep 0.1; done
export DISPLAY=":$(cat "$work/display")"
roslaunch -p "$port" smartcar_gym_ros smartcar_policy.launch >"$work/launch.log" 2>&1 &
pids+=($!)
# rviz's window, and the policy node ready (it publishes cmd_vel once its model is loaded)
for _ in $(seq 120); do
  window="$(xdotool search --onlyvisible --name 'RViz' 2>/dev/null | head -1 || true)"
  if [ -n "$window" ] && rostopic info /cmd_vel 2>/dev/null | grep -q smartcar_policy; then break; fi
  sleep 1
done
[ -n "$window" ] || { cat "$work/launch.log"; echo "rviz did not start" >&2; exit 1; }
sleep 5  # rviz lays out its panels and draws the robot
# zoom in on the car with the mouse wheel (the view's focus stays on the odom origin)
xdotool mousemove --window "$window" 660 364 click --repeat "${ZOOM:-6}" --delay 150 4
sleep 1
# 2D Nav Goal: the g key (no window manager: the key goes to the window under the pointer),
# then press at the goal and drag toward the heading
xdotool mousemove --window "$window" "${GOAL_X:-588}" "${GOAL_Y:-540}" sleep 0.5 key g sleep 0.5
xdotool mousedown 1 sleep 0.3 mousemove_relative 40 0 sleep 0.3 mouseup 1
grep -q "new goal" "$work/launch.log" || sleep 2
sleep "${SHOT_AFTER:-8}"
import -window "$window" "$out"
grep -E "new goal|reached|refused|dropped" "$work/launch.log" || true
echo "wrote $out"
