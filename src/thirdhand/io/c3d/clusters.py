"""Marker clusters: grouping labels into bodies, cluster geometry and rigid fits."""

from __future__ import annotations

import warnings
import zlib
from collections import Counter
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from thirdhand import se3
from thirdhand.arrays import FloatArray
from thirdhand.demonstration import Demonstration
from thirdhand.errors import ThirdhandError
from thirdhand.io.c3d.constants import MIN_CLUSTER

_MAX_MEDIAN_FRAMES = 4000
_MIN_WELL_SEEN = 10  # complete frames needed to take the median geometry from them alone


def group_by_prefix(labels: Sequence[str]) -> dict[str, list[str]]:
    """Group marker labels into bodies by prefix.

    The prefix is what precedes the first ``:``, else the last ``/``, else the
    last ``_``; prefixes shared by at least 3 markers become bodies.

    Parameters
    ----------
    labels : sequence of str
        Marker labels, in file order.

    Returns
    -------
    dict body name -> list of labels
        In order of first appearance.
    """
    groups: dict[str, list[str]] = {}
    for lab in labels:
        prefix = label_prefix(lab)
        if prefix:
            groups.setdefault(prefix, []).append(lab)
    return {k: v for k, v in groups.items() if len(v) >= MIN_CLUSTER}


def label_prefix(label: str) -> str | None:
    """Body prefix of a marker label (see :func:`group_by_prefix`), None if it has none."""
    if ":" in label:
        head = label.split(":", 1)[0]
    elif "/" in label.strip("/"):
        head = label.rstrip("/").rsplit("/", 1)[0]
    elif "_" in label:
        head = label.rsplit("_", 1)[0]
    else:
        return None
    return head or None


def reference_cluster(xyz: ArrayLike) -> FloatArray:
    """A cluster's marker coordinates in a body frame built from the data.

    See the module docstring for the convention (first well-seen frame, median
    geometry, centroid origin, principal axes).

    Parameters
    ----------
    xyz : array_like, shape (n_frames, m, 3), metres, world frame
        The cluster's markers over time; NaN where missing.

    Returns
    -------
    ndarray, shape (m, 3), metres, body frame
        NaN rows for markers never seen in a frame that could be fitted; all NaN
        when no frame sees 3 markers.
    """
    obs = np.asarray(xyz, dtype=np.float64)
    m = obs.shape[1]
    seen = np.all(np.isfinite(obs), axis=2)
    counts = seen.sum(axis=1)
    if counts.size == 0 or counts.max() < MIN_CLUSTER:
        return np.full((m, 3), np.nan)
    first = int(np.argmax(counts == counts.max()))
    ref0 = canonical_cluster(obs[first])
    use = np.all(np.isfinite(ref0), axis=1)
    idx = np.flatnonzero(counts == m)
    if idx.size < _MIN_WELL_SEEN:  # too few complete frames: any frame that can be fitted
        idx = np.flatnonzero(seen[:, use].sum(axis=1) >= MIN_CLUSTER)
    if idx.size > _MAX_MEDIAN_FRAMES:  # evenly spread frames are plenty for a median
        idx = idx[np.linspace(0, idx.size - 1, _MAX_MEDIAN_FRAMES).round().astype(int)]
    p, q, _ = se3.kabsch(ref0[use], obs[idx][:, use])
    local = se3.quat_rotate(se3.quat_conjugate(q)[:, None], obs[idx] - p[:, None])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN marker: stays NaN
        median = np.nanmedian(local, axis=0)
    return canonical_cluster(median)


def canonical_cluster(points: ArrayLike) -> FloatArray:
    """Express a marker cluster in its centroid / principal-axes frame.

    Parameters
    ----------
    points : array_like, shape (m, 3), metres
        Marker positions in any frame; NaN rows (unseen markers) are ignored
        and stay NaN.

    Returns
    -------
    ndarray, shape (m, 3), metres, body frame
        Origin at the centroid of the finite rows; x, y, z along the principal
        axes by decreasing spread, right-handed, signs as in the module docstring.
    """
    pts = np.asarray(points, dtype=np.float64)
    ok = np.all(np.isfinite(pts), axis=1)
    centred = pts - pts[ok].mean(axis=0)
    _, vecs = np.linalg.eigh(centred[ok].T @ centred[ok])
    axes = vecs[:, ::-1].copy()
    for j in (0, 1):
        proj = centred[ok] @ axes[:, j]
        big = np.flatnonzero(np.abs(proj) > 0.1 * np.abs(proj).max())
        if big.size and proj[big[0]] < 0:
            axes[:, j] *= -1.0
    axes[:, 2] = np.cross(axes[:, 0], axes[:, 1])
    out: FloatArray = centred @ axes
    return out


def fit_cluster(reference: ArrayLike, xyz: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Body poses from its markers by a per-frame Kabsch fit.

    Parameters
    ----------
    reference : array_like, shape (m, 3), metres, body frame
        Marker coordinates in the body frame; NaN rows are left out of the fit.
    xyz : array_like, shape (n_frames, m, 3), metres, world frame
        Observed markers; NaN where missing (weight 0).

    Returns
    -------
    pos : ndarray, shape (n_frames, 3), metres, world frame
    quat : ndarray, shape (n_frames, 4), x y z w, sign-continuous
    rms : ndarray, shape (n_frames,), metres
        NaN where fewer than 3 markers were seen.
    """
    ref = np.asarray(reference, dtype=np.float64)
    obs = np.asarray(xyz, dtype=np.float64)
    use = np.all(np.isfinite(ref), axis=1)
    n = obs.shape[0]
    if use.sum() < MIN_CLUSTER:
        return np.full((n, 3), np.nan), np.full((n, 4), np.nan), np.full(n, np.nan)
    p, q, rms = se3.kabsch(ref[use], obs[:, use])
    return p, se3.quat_make_continuous(q), rms


def default_cluster(name: str) -> FloatArray:
    """The marker cluster :func:`write` gives a body by default.

    Four non-coplanar markers 3 to 6 cm from the body origin in an irregular
    tetrahedron, turned by a rotation seeded from the body name: the same for a
    given name in every run, different between bodies.

    Returns
    -------
    ndarray, shape (4, 3), metres, body frame
    """
    rng = np.random.default_rng(zlib.crc32(name.encode("utf-8")))
    base = np.array(
        [[0.05, 0.0, 0.0], [0.0, 0.04, 0.0], [0.0, 0.0, 0.035], [-0.03, -0.035, -0.025]]
    )
    base *= rng.uniform(0.85, 1.15, size=(4, 1))
    rot = se3.matrix_from_quat(se3.random_quat(rng))
    out: FloatArray = base @ rot.T
    return out


def markers_from_demonstration(
    demo: Demonstration, clusters: Mapping[str, ArrayLike] | None = None
) -> tuple[list[str], FloatArray]:
    """Marker trajectories of a demonstration's bodies (the marker-level view of a scene).

    Parameters
    ----------
    demo : Demonstration
    clusters : mapping body name -> array_like, shape (m, 3), metres, body frame, optional
        Marker offsets of oriented bodies (m >= 3, not collinear); others get
        :func:`default_cluster`.

    Returns
    -------
    labels : list of str
        ``"<body>:M<k>"`` (k from 1) for oriented bodies, the body name for
        position-only bodies.
    positions : ndarray, shape (n_frames, n_markers, 3), metres, world frame
        NaN where the body is not tracked.

    Raises
    ------
    ThirdhandError
        For a cluster of an unknown or position-only body, of fewer than 3
        markers, collinear or not finite, or duplicate labels.
    """
    labels, offsets = _layout(demo, clusters)
    cols: list[FloatArray] = []
    for name in demo.body_names:
        tr = demo.track(name)
        off = offsets.get(name)
        if off is None:
            cols.append(tr.pos[:, None])
        else:
            cols.append(tr.pos[:, None] + se3.quat_rotate(tr.quat[:, None], off[None]))
    if not cols:
        return labels, np.zeros((demo.n_frames, 0, 3))
    return labels, np.concatenate(cols, axis=1)


def _layout(
    demo: Demonstration, clusters: Mapping[str, ArrayLike] | None
) -> tuple[list[str], dict[str, FloatArray]]:
    """Marker labels and offsets (oriented bodies only) in body order."""
    given = dict(clusters or {})
    unknown = sorted(set(given) - set(demo.body_names))
    if unknown:
        raise ThirdhandError(f"clusters given for unknown bod(ies) {', '.join(unknown)}")
    labels: list[str] = []
    offsets: dict[str, FloatArray] = {}
    for info in demo.bodies:
        # C3D readers strip the blanks around labels: the labels are made without them.
        stem = info.name.strip()
        if not stem:
            raise ThirdhandError(f"body {info.name!r}: a blank name makes no marker label")
        if not info.oriented:
            if info.name in given:
                raise ThirdhandError(f"body {info.name!r} is position-only: it takes no cluster")
            labels.append(stem)
            continue
        off = (
            _check_offsets(info.name, given[info.name])
            if info.name in given
            else default_cluster(info.name)
        )
        offsets[info.name] = off
        labels.extend(f"{stem}:M{k + 1}" for k in range(off.shape[0]))
    counts = Counter(labels)
    dup = sorted(lab for lab, k in counts.items() if k > 1)
    if dup:
        raise ThirdhandError(f"duplicate marker label(s) {', '.join(dup)}")
    long = [lab for lab in counts if len(lab.encode("utf-8")) > 255]
    if long:
        raise ThirdhandError(f"marker label {long[0]!r} is longer than C3D's 255 bytes")
    return labels, offsets


def _check_offsets(name: str, offsets: ArrayLike) -> FloatArray:
    off = np.asarray(offsets, dtype=np.float64)
    if off.ndim != 2 or off.shape[1] != 3 or off.shape[0] < MIN_CLUSTER:
        raise ThirdhandError(
            f"body {name!r}: a cluster needs shape (m >= {MIN_CLUSTER}, 3), got {off.shape}"
        )
    if not np.all(np.isfinite(off)):
        raise ThirdhandError(f"body {name!r}: cluster offsets must be finite")
    sv = np.linalg.svd(off - off.mean(axis=0), compute_uv=False)
    if sv[1] <= 1e-6:
        raise ThirdhandError(f"body {name!r}: cluster markers are collinear; orientation is lost")
    return off
