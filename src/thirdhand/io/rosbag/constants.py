"""Constants and array aliases shared by the ROS bag reader and writer."""

from __future__ import annotations

import os

PathLike = str | os.PathLike[str]

FORMAT_VERSION = "thirdhand.rosbag/1"
#: Topic of the JSON message that makes a bag written by :func:`write` round-trip.
META_TOPIC = "/thirdhand/meta"
#: Default largest spread of stamps merged into one frame, seconds.
DEFAULT_MERGE_TOLERANCE = 1e-3

_NS = 1_000_000_000
_ROS2_SUFFIXES = (".mcap", ".db3")
_TFMESSAGE = "tf2_msgs/msg/TFMessage"
_POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
_STRING = "std_msgs/msg/String"
