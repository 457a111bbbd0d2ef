"""ROS 1 and ROS 2 bags: poses from pose topics, the tf tree and world-model messages.

Reading (through the pure-Python ``rosbags`` package; no ROS installation needed)
-------------------------------------------------------------------------------
Sources: a ROS 1 ``.bag`` file (or a list of them, e.g. one recording split in
parts, or a folder of such parts, read in name order), a ROS 2 bag folder
(``metadata.yaml`` plus ``.db3`` or ``.mcap`` files), or a lone ``.mcap`` /
``.db3`` file. Message definitions embedded in the bag (ROS 1 connections
always carry them) are registered, so custom types decode.

Every topic is classified by the *structure* of its message type, not its name:

- **pose** topics: a ``geometry_msgs/Pose`` at ``msg``, ``msg.pose`` or
  ``msg.pose.pose`` (``PoseStamped``, ``PoseWithCovarianceStamped``,
  ``Odometry``...). One body per topic, named after the topic without its
  leading slash. When the header's frame belongs to the tf tree of
  ``root_frame``, the pose is moved into ``root_frame`` (tf looked up at the
  message's stamp); otherwise it stays in its header frame.
- **tf**: ``tf2_msgs/TFMessage`` (``/tf``; ``/tf_static`` for static transforms)
  and ``TransformStamped`` topics. Every ``child_frame_id`` becomes a body whose
  pose is expressed in ``root_frame`` (default: the root of the largest tree),
  composed along the tree. A body is observed at the stamps of the deepest
  non-static transform on its path; the other non-static transforms are
  interpolated there (linear / slerp, no extrapolation, as tf2 does); static
  transforms take the latest value published at or before that time (the
  first one before it was published).
- **world model**: a message holding an array of objects, each with an integer
  ``id``, a pose (``PoseStamped`` or ``Pose``) and optionally a boolean field
  whose name contains ``visible``. One body per id, named ``<object_prefix><id>``
  (``ar_0``, ``ar_13`` for AR tags); a frame where the object is not visible is
  invalid.

Topics of other types (joint states, controller states...) are listed in
``meta["unused_topics"]``.

Time stamps come from the message's ``header.stamp`` (for world-model objects:
the pose's, else the object's, else the message's header), falling back to
the bag's receive time when the stamp is zero (unset).

Time axis: the union of all observation stamps, merged so that bodies
published together share a frame: a frame opens at the earliest stamp not yet
placed and takes every later stamp within ``merge_tolerance`` of it, at most one
per body (stream); its time is that earliest stamp. A body is invalid at the
frames where it was not observed. ``t`` is in seconds from the first frame;
``meta["start_time_unix"]`` (float seconds) and ``meta["start_time_ns"]`` (int)
give the absolute time of ``t = 0``.

Writing
-------
ROS 1 ``.bag``, ROS 2 folder (mcap or sqlite3 storage) or a lone ``.mcap`` /
``.db3`` file, with one ``geometry_msgs/PoseStamped`` topic per body
(``/thirdhand/<name>/pose``) or the bodies as ``/tf`` frames under
``root_frame``. Invalid frames are not published. A ``/thirdhand/meta``
``std_msgs/String`` message holds JSON with the body metadata, labels, the
demonstration's ``meta`` and the time origin, so that a bag written here reads
back with the same time axis (to the nanosecond), poses, bodies and labels.

Modules
-------
:mod:`~thirdhand.io.rosbag.reader` (``read``, ``sniff``) decodes messages with
:mod:`~thirdhand.io.rosbag.collect`, sorting topics by
:mod:`~thirdhand.io.rosbag.classify`; :mod:`~thirdhand.io.rosbag.timeline` builds
the frame axis and sample series, :mod:`~thirdhand.io.rosbag.tree` the tf tree,
and :mod:`~thirdhand.io.rosbag.assemble` the demonstration.
:mod:`~thirdhand.io.rosbag.writer` holds ``write``.
"""

from thirdhand.io.rosbag.constants import DEFAULT_MERGE_TOLERANCE, FORMAT_VERSION, META_TOPIC
from thirdhand.io.rosbag.reader import read, sniff
from thirdhand.io.rosbag.writer import write

__all__ = ["DEFAULT_MERGE_TOLERANCE", "FORMAT_VERSION", "META_TOPIC", "read", "sniff", "write"]
