"""The ROS 1 bridge: the simulated smartcar and trained policies as rospy nodes, bags of episodes.

Importing this package imports neither rospy nor pybullet; the modules do what they say:

* ``debian``: Debian's rospy and message packages in this Python, one line when missing.
* ``messages``: ROS messages from the robot's state (rospy's classes or a rosbags typestore)
  and what the policy reads back from received messages.
* ``params``: the bringup node's ArbotiX configuration, from its private ROS parameters as
  ``arbotix_driver`` reads them, else from a file.
* ``timing``: publication instants on the simulator's clock, wall-clock pacing.
* ``bringup``: the ``bringup`` node (``SmartCarRobot`` in a ``Simulator``).
* ``settings``: what the policy node needs of the env a policy was trained in.
* ``driving``: the policy node's decisions (``GoalDriver``), free of rospy.
* ``policy``: the ``policy`` node.
* ``bag``: evaluated episodes as a ROS 1 bag or MCAP file (``smartcar-eval --bag``; rosbags).
* ``package``: where the shipped ROS package ``smartcar_gym_ros`` lies.
* ``cli``: the ``smartcar-ros`` command.
"""
