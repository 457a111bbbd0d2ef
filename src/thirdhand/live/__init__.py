"""The live loop: follow a person assembling, know the plan step, have the robot assist.

Modules: :mod:`~thirdhand.live.source` (the frame-iterator interface and a
replay), :mod:`~thirdhand.live.features` and :mod:`~thirdhand.live.filter`
(the segmentation CRF run causally), :mod:`~thirdhand.live.state` (which of
the plan's constraints hold now), :mod:`~thirdhand.live.tracker` (plan
progress), :mod:`~thirdhand.live.loop` (one update per frame, latency),
:mod:`~thirdhand.live.assist` (the simulated robot fetching the next part) and
:mod:`~thirdhand.live.cli` (``thirdhand live``). See ``docs/explanation/live.md``.
"""
