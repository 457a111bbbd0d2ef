"""Perception: head pose and attention from a camera, pointing gestures from tracked fingers.

The 3rdHand report's instruction protocols go beyond demonstrations: a person
also instructs through where they look and what they point at.

- :mod:`~thirdhand.perception.video`, :mod:`~thirdhand.perception.landmarks`,
  :mod:`~thirdhand.perception.headpose`, :mod:`~thirdhand.perception.track`: face
  landmarks (MediaPipe's face mesh, shipped in its wheel), head pose with
  ``cv2.solvePnP`` against the canonical face model, relative to a calibration
  frame, eye regions from the iris points. Needs the ``perception`` extra.
- :mod:`~thirdhand.perception.attention`: which object a head or gaze ray
  attends to over time (cone and hysteresis), as intervals.
- :mod:`~thirdhand.perception.pointing`: pointing gestures from tracked thumb,
  index and middle fingertips, as ``pointed(hand, object, t0, t1)`` events.
- :mod:`~thirdhand.perception.events`: those events in a task file's
  ``stages.perception`` block, and the object in focus at a given time.

Only the video half imports OpenCV and MediaPipe, lazily; the rest is numpy.
"""

from thirdhand.perception.attention import (
    AttentionInterval,
    attention_intervals,
    head_rays,
    object_centres,
)
from thirdhand.perception.events import add_perception_events, focus_object, perception_events
from thirdhand.perception.pointing import PointingEvent, detect_pointing

__all__ = [
    "AttentionInterval",
    "PointingEvent",
    "add_perception_events",
    "attention_intervals",
    "detect_pointing",
    "focus_object",
    "head_rays",
    "object_centres",
    "perception_events",
    "track_head",
]


def __getattr__(name: str) -> object:
    if name == "track_head":  # keeps ``import thirdhand.perception`` free of OpenCV
        from thirdhand.perception.track import track_head

        return track_head
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
