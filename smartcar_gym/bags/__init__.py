"""ROS data without ROS: the messages the bridge and the bags carry (``messages``, ``cdr``),
evaluated episodes as ROS 1 bags or MCAP files (``ros1``: ``smartcar-eval --bag``) and as ROS 2
bags (``ros2``: ``smartcar-eval --bag DIR --bag-format ros2``), written with rosbags and mcap
(the ``ros`` extra)."""
