"""A ROS node for tests/test_ros_live.py, run in its own process (rospy reconfigures logging and
signals of the process it runs in): records topics, publishes, drives, and prints JSON.

    python ros_probe.py '{"record": {"/odom": "nav_msgs/Odometry"}, "duration": 3}'

Keys: ``record`` (topic -> type), ``duration`` (wall s after the subscriptions connect),
``publish`` (list of {"after": wall s, "topic", "type", "msg": fields}), ``drive`` ({"linear",
"angular", "duration", "align"}: cmd_vel on every /clock tick for ``duration`` simulated s
from the second multiple of ``align`` after the first tick seen, then one zero twist),
``until_rosout`` (stop as soon as a log line contains this text), ``until_stamp``
({"topic", "after_drive"}: stop once that topic has a message stamped that long after the
drive started), ``wait_for`` (topics
that must have a publisher before the clock starts), ``grace`` (s recorded after the awaited
line). Output on stdout: {"topics": {topic: [{"t": s since the start, "wall": time.time(),
"stamp": header stamp, "f": [fields]}]}, "rosout": [[node, level, text]]}, or {"error": why}
when what it waits for has not connected after ``connect_timeout`` (s, 30 by default).

The log lines come from ``/rosout_agg``, as rqt_console reads them: the rosout node, up since
roscore started, gathers every node's ``/rosout``, and the probe's one connection to it is made
before its clock starts. (Subscribing ``/rosout`` itself, the probe could not tell when it is
connected to a node that registers while it starts, as the policy node does after loading
torch.)
"""

from __future__ import annotations

import json
import math
import sys
import time

from smartcar_gym.ros.debian import import_ros


def fields(msg):
    """The values a test looks at, by message type."""
    kind = msg._type
    if kind == "nav_msgs/Odometry":
        p, q, t = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist
        return [msg.header.frame_id, msg.child_frame_id, p.x, p.y, q.z, q.w, t.linear.x,
                t.angular.z]
    if kind == "geometry_msgs/Twist":
        return [msg.linear.x, msg.angular.z]
    if kind == "tf2_msgs/TFMessage":
        return [[t.header.frame_id, t.child_frame_id] for t in msg.transforms]
    if kind == "sensor_msgs/JointState":
        return [list(msg.name), list(msg.position)]
    return []


def main() -> None:
    spec = json.loads(sys.argv[1])
    ros = import_ros()
    rospy = ros.rospy
    import genpy
    import roslib.message

    rospy.init_node("probe", anonymous=True, disable_signals=True)
    record = {topic: [] for topic in spec.get("record", {})}
    rosout = []
    done = {"flag": False}
    until_stamp = spec.get("until_stamp")  # {"topic": ..., "after_drive": s}
    drive_state = {"start": None, "stopped": False}

    def recorder(topic):
        def callback(msg):
            header = getattr(msg, "header", None)
            if header is None and getattr(msg, "transforms", None):
                header = msg.transforms[0].header
            stamp = header.stamp.to_sec() if header is not None else None
            record[topic].append({"t": time.monotonic(), "wall": time.time(), "stamp": stamp,
                                  "f": fields(msg)})
            if (until_stamp and topic == until_stamp["topic"] and drive_state["start"] is not None
                    and stamp >= drive_state["start"] + until_stamp["after_drive"]):
                done["flag"] = True
        return callback

    for topic, kind in spec.get("record", {}).items():
        rospy.Subscriber(topic, roslib.message.get_message_class(kind), recorder(topic))
    until = spec.get("until_rosout")

    def on_log(msg):
        rosout.append([msg.name, msg.level, msg.msg])
        if until and until in msg.msg:
            done["flag"] = True

    logs = rospy.Subscriber("/rosout_agg", ros.rosgraph_msgs.Log, on_log)
    publishers = {}
    for item in spec.get("publish", []):
        cls = roslib.message.get_message_class(item["type"])
        publishers[item["topic"]] = rospy.Publisher(item["topic"], cls, queue_size=10)
    drive = spec.get("drive")
    if drive:
        cmd = rospy.Publisher("/cmd_vel", ros.geometry_msgs.Twist, queue_size=10)

        def on_clock(msg):
            now = msg.clock.to_sec()
            if drive_state["start"] is None:  # the second aligned instant from now
                drive_state["start"] = (math.floor(now / drive["align"]) + 2) * drive["align"]
            start = drive_state["start"]
            if drive_state["stopped"] or now < start:
                return
            twist = ros.geometry_msgs.Twist()
            if now < start + drive["duration"]:
                twist.linear.x, twist.angular.z = drive["linear"], drive["angular"]
            else:
                drive_state["stopped"] = True
            cmd.publish(twist)

    connect_timeout = spec.get("connect_timeout", 30)
    deadline = time.monotonic() + connect_timeout
    for topic in spec.get("wait_for", []):  # the node under test is up and publishing
        while not rospy.get_published_topics() or topic not in dict(
                rospy.get_published_topics()):
            if time.monotonic() > deadline:
                print(json.dumps({"error": f"no publisher of {topic}"}))
                return
            time.sleep(0.05)
    waiting = {**{f"a subscriber of {topic}": p for topic, p in publishers.items()},
               "the rosout node (/rosout_agg)": logs}
    while waiting:  # a message published before its subscriber connects goes to nobody
        waiting = {what: link for what, link in waiting.items()
                   if link.get_num_connections() == 0}
        if waiting and time.monotonic() > deadline:
            print(json.dumps({"error": f"{', '.join(waiting)}: not connected after "
                                       f"{connect_timeout} s"}))
            return
        time.sleep(0.05)
    if drive:
        rospy.Subscriber("/clock", ros.rosgraph_msgs.Clock, on_clock)
    start = time.monotonic()
    pending = sorted(spec.get("publish", []), key=lambda item: item["after"])
    end = start + spec["duration"]
    while time.monotonic() < end:
        if done["flag"]:  # what the awaited line announced is on its way: let it arrive
            end = min(end, time.monotonic() + spec.get("grace", 0.3))
            done["flag"] = False
        now = time.monotonic() - start
        while pending and pending[0]["after"] <= now:
            item = pending.pop(0)
            cls = roslib.message.get_message_class(item["type"])
            msg = cls()
            genpy.message.fill_message_args(msg, [item["msg"]])
            publishers[item["topic"]].publish(msg)
        time.sleep(0.01)
    for rows in record.values():
        for row in rows:
            row["t"] -= start
    print(json.dumps({"topics": record, "rosout": rosout, "elapsed": time.monotonic() - start,
                      "drive_start": drive_state["start"]}))
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
