"""C3D motion-capture files (through ``ezc3d``): markers in, rigid bodies out, and back.

Reading
-------
A C3D file holds marker trajectories (``POINT`` data): per frame and marker a
position and a residual. A marker is *missing* in a frame when its residual is
negative, a coordinate is NaN, or all three coordinates are exactly zero.
Positions are converted from ``POINT:UNITS`` (``mm``, ``cm``, ``m``, ``in``;
absent means millimetres, the C3D default) to metres. The time axis is
``t_i = (first_frame + i) / rate`` seconds, with ``first_frame`` the header's
0-based first frame and ``rate`` the point rate (``POINT:RATE``).

Rigid bodies are fitted to clusters of at least 3 markers by a weighted
least-squares (Kabsch) fit per frame, missing markers weighted 0; a frame with
fewer than 3 seen markers is invalid. The clusters come from, in order:

1. the ``bodies`` option ``{body: [marker labels]}``;
2. a ``THIRDHAND`` parameter group written by :func:`write`;
3. the labels' prefixes: ``Seat:M1`` (everything before the first ``:``), else
   ``chair/seat/M1`` (before the last ``/``), else ``Seat_M1`` (before the last
   ``_``); a prefix shared by at least 3 markers makes a body of that name,
   unless the group is not rigid (median fit residual above ``max_rms``, 5 mm
   by default: a person's skin markers, a Vicon subject's skeleton).

Body frame convention
---------------------
When the file carries a ``THIRDHAND`` group, each cluster's marker coordinates
in the body frame are read from it, so the bodies written by :func:`write` come
back with their original poses. Otherwise the body frame is built from the data:

1. the first frame where every marker of the cluster is seen (else the first
   frame seeing the most markers, at least 3) gives a provisional cluster;
2. the well-seen frames (those seeing every marker, when there are at least
   10 of them; else every frame seeing 3 markers of the provisional cluster) are
   fitted to it, each seen marker is expressed in the provisional body frame,
   and the per-coordinate median over frames gives the cluster's geometry
   (robust to noise and occasional mislabelled frames);
3. the body frame of that median cluster has its origin at the centroid of the
   markers and its axes along the cluster's principal axes, x the direction of
   largest spread, then y, and z = x × y (right-handed). The sign of x and y is
   chosen so that the first marker (in label order) whose coordinate along that
   axis exceeds 10 % of the largest one has a positive coordinate.

Such a frame is arbitrary but fixed for a recording: relative motions (the pose
of one body in another, rotation angles) are exact, absolute orientations are
not those of any CAD model. A collinear cluster leaves the rotation about its
line undetermined.

Writing
-------
:func:`write` turns each oriented body into a cluster of markers (by default 4
non-coplanar markers 3 to 6 cm from the body origin, the same for a given body
name), each position-only body into one marker, and writes them in millimetres
as float32 with residual 0 (seen) or -1 and NaN (missing). A ``THIRDHAND``
parameter group holds, as JSON, the body metadata, marker labels, cluster
offsets (float64), exact time axis, labels and ``meta``, so ``read(write(demo))``
returns the demonstration up to float32 storage of the markers (positions to
well under 1e-5 m, orientations to under 1e-4 rad for clusters of a few cm).
The time axis must be regular, and ``ezc3d`` stores at most 65535 frames.

Markers that belong to no body are dropped, or with ``markers_as_bodies=True``
kept as position-only bodies (:attr:`BodyInfo.oriented` False) named by their label.

Damaged files
-------------
ezc3d trusts the sizes written in a file, and crashes the interpreter on some
damaged parameter sections; it also reads a truncated file silently. The header
and every parameter record are therefore checked first, and a file shorter than
the frames it announces raises :class:`FormatError` (or, with
``allow_truncated=True``, yields its complete frames).

Modules
-------
:mod:`~thirdhand.io.c3d.reader` (``read``) builds bodies from the markers that
:mod:`~thirdhand.io.c3d.markers` loads after the checks of
:mod:`~thirdhand.io.c3d.structure` (``sniff``); :mod:`~thirdhand.io.c3d.clusters`
holds the cluster geometry and fits, :mod:`~thirdhand.io.c3d.writer` ``write``.
"""

from thirdhand.io.c3d.clusters import (
    canonical_cluster,
    default_cluster,
    fit_cluster,
    group_by_prefix,
    label_prefix,
    markers_from_demonstration,
    reference_cluster,
)
from thirdhand.io.c3d.constants import FORMAT_VERSION, GROUP, MAX_FRAMES, UNIT_SCALES
from thirdhand.io.c3d.reader import read
from thirdhand.io.c3d.structure import sniff
from thirdhand.io.c3d.writer import write

__all__ = [
    "FORMAT_VERSION",
    "GROUP",
    "MAX_FRAMES",
    "UNIT_SCALES",
    "canonical_cluster",
    "default_cluster",
    "fit_cluster",
    "group_by_prefix",
    "label_prefix",
    "markers_from_demonstration",
    "read",
    "reference_cluster",
    "sniff",
    "write",
]
