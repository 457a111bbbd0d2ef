"""Labelled kinesthetic recordings in the layout of Figueroa & Billard (``ICSC-HMM`` test data).

Two MATLAB layouts, read with ``scipy.io.loadmat`` (MATLAB v5/v7; a v7.3 / HDF5
file is read with ``h5py`` when it is installed):

- ``proc_data`` (struct array, one element per demonstration, fields ``X``
  13 × T — position (m), quaternion **w x y z**, force (N), torque (N m) — and
  ``dt`` (s), optionally ``name``) with ``True_states`` (cell array of T labels);
- ``Data_<suffix>`` (cell array of 13·A × T matrices, A arms, the same 13 rows per
  arm, no time axis) with ``True_states_<suffix>`` (cell array of T labels).
  These carry no time: ``rate_hz`` says it (default :data:`DEFAULT_RATE_HZ`, the
  rate of the ``proc_data`` recordings of the same robots), recorded in
  :attr:`LabelledStream.rate_assumed`.

The quaternion order was checked against the homogeneous poses ``H`` of the
wiping file (``w x y z`` matches to 1e-13 rad, ``x y z w`` is up to 180° off); it is
converted to thirdhand's ``x y z w``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand.arrays import FloatArray, IntArray
from thirdhand.errors import FormatError
from thirdhand.se3 import quat_make_continuous

#: Sampling rate assumed for ``Data_*`` streams, which carry no time, Hz.
DEFAULT_RATE_HZ = 100.0
#: Rows per arm: position 3, quaternion (w x y z) 4, force 3, torque 3.
ROWS_PER_ARM = 13


@dataclass(frozen=True)
class ArmTrack:
    """One arm's end-effector signals.

    Attributes
    ----------
    pos : ndarray, shape (n, 3)
        Position, metres, robot base frame.
    quat : ndarray, shape (n, 4)
        Orientation, unit quaternion x y z w, sign-continuous.
    force : ndarray, shape (n, 3)
        Measured force, newtons.
    torque : ndarray, shape (n, 3)
        Measured torque, newton metres.
    """

    pos: FloatArray
    quat: FloatArray
    force: FloatArray
    torque: FloatArray


@dataclass(frozen=True)
class LabelledStream:
    """One recording with a human's per-sample phase labels.

    Attributes
    ----------
    name : str
        ``file.mat[i]`` or the recording's own name.
    t : ndarray, shape (n,)
        Seconds from the first sample.
    arms : tuple of ArmTrack
        One per arm (the first is the active arm in the bimanual files).
    labels : ndarray of int, shape (n,)
        Phase label per sample, as in the file (1-based).
    rate_assumed : bool
        Whether the time axis comes from an assumed rate (no ``dt`` in the file).
    """

    name: str
    t: FloatArray
    arms: tuple[ArmTrack, ...]
    labels: IntArray
    rate_assumed: bool = False

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.t.size)

    @property
    def boundaries(self) -> FloatArray:
        """Times of the label changes, seconds (midway between the two samples)."""
        k = np.flatnonzero(np.diff(self.labels) != 0)
        return 0.5 * (self.t[k] + self.t[k + 1])


def _load(path: Path) -> dict[str, Any]:
    import scipy.io

    try:
        return dict(scipy.io.loadmat(path, squeeze_me=True, struct_as_record=False))
    except NotImplementedError:  # MATLAB v7.3: HDF5
        pass
    except Exception as exc:  # scipy raises anything from MatReadError to IndexError on junk
        raise FormatError(path, f"not a readable MATLAB .mat file: {exc}") from None
    try:
        import h5py
    except ImportError:
        raise FormatError(
            path, "a MATLAB v7.3 (HDF5) file needs h5py; save it with -v7 or install h5py"
        ) from None
    out: dict[str, Any] = {}
    with h5py.File(path, "r") as fh:
        for key in fh:
            if key.startswith("#"):
                continue
            obj = fh[key]
            if isinstance(obj, h5py.Dataset) and obj.dtype == object:
                out[key] = np.array(
                    [np.asarray(fh[ref]).T for ref in np.asarray(obj).ravel()], dtype=object
                )
            elif isinstance(obj, h5py.Dataset):
                out[key] = np.asarray(obj).T
            else:
                out[key] = _H5Struct({k: np.asarray(v).T for k, v in obj.items()})
    return out


class _H5Struct:
    """A struct read from HDF5, with its fields as attributes."""

    def __init__(self, fields: dict[str, Any]) -> None:
        self._fieldnames = list(fields)
        self.__dict__.update(fields)


def _cells(value: Any) -> list[Any]:
    """A MATLAB cell/struct array squeezed by loadmat as a list of its elements."""
    if isinstance(value, np.ndarray) and value.dtype == object:
        return list(value.ravel())
    return [value]  # a single element (one demonstration) is not wrapped by loadmat


def _arms(x: Any, path: Path, where: str) -> tuple[ArmTrack, ...]:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim != 2 or a.shape[0] % ROWS_PER_ARM or a.shape[0] == 0:
        raise FormatError(
            path,
            f"expected {ROWS_PER_ARM} rows per arm (position 3, quaternion w x y z 4, "
            f"force 3, torque 3) × samples, got shape {a.shape}",
            where=where,
        )
    if not np.isfinite(a).all():
        col = int(np.argmax(~np.isfinite(a).all(axis=0)))
        raise FormatError(path, f"sample {col} is not finite (NaN or inf)", where=where)
    arms = []
    for i in range(a.shape[0] // ROWS_PER_ARM):
        b = a[i * ROWS_PER_ARM : (i + 1) * ROWS_PER_ARM].T
        norms = np.linalg.norm(b[:, 3:7], axis=1)
        if np.abs(norms - 1.0).max() > 1e-3:
            k = int(np.argmax(np.abs(norms - 1.0)))
            raise FormatError(
                path,
                f"arm {i} rows 4-7 should be a unit quaternion, sample {k} has norm {norms[k]:.4g}",
                where=where,
            )
        q = quat_make_continuous(b[:, [4, 5, 6, 3]] / norms[:, None])
        arms.append(ArmTrack(b[:, 0:3].copy(), q, b[:, 7:10].copy(), b[:, 10:13].copy()))
    return tuple(arms)


def _labels(value: Any, n: int, path: Path, where: str) -> IntArray:
    lab = np.asarray(value).ravel()
    if lab.size != n:
        raise FormatError(
            path, f"expected {n} labels (one per sample), got {lab.size}", where=where
        )
    if not np.issubdtype(lab.dtype, np.number) or not np.all(np.isfinite(lab.astype(float))):
        raise FormatError(path, "labels must be finite numbers", where=where)
    if np.any(lab != np.round(lab)):
        raise FormatError(path, "labels must be whole numbers", where=where)
    return lab.astype(np.int64)


def read_labelled_mat(
    path: str | os.PathLike[str], *, rate_hz: float | None = None
) -> list[LabelledStream]:
    """Read every labelled recording of a ``.mat`` file of the Figueroa layout.

    Parameters
    ----------
    path : path-like
    rate_hz : float, optional
        Sampling rate of ``Data_*`` streams (they carry no time), Hz; default
        :data:`DEFAULT_RATE_HZ`. Ignored for ``proc_data``, which has ``dt``.

    Returns
    -------
    list of LabelledStream

    Raises
    ------
    FormatError
        In one line: the file, the variable or element, and what was expected.
    """
    p = Path(path)
    if not p.is_file():
        raise FormatError(p, "no such file")
    m = {k: v for k, v in _load(p).items() if not k.startswith("__")}
    if "proc_data" in m:
        if "True_states" not in m:
            raise FormatError(p, "has proc_data but no True_states (the per-sample labels)")
        demos, labs = _cells(m["proc_data"]), _cells(m["True_states"])
        if len(demos) != len(labs):
            raise FormatError(p, f"{len(demos)} proc_data elements but {len(labs)} True_states")
        out = []
        for i, (d, lab) in enumerate(zip(demos, labs, strict=True)):
            where = f"proc_data[{i}]"
            for f in ("X", "dt"):
                if not hasattr(d, f):
                    raise FormatError(p, f"missing field {f!r}", where=where)
            dt = float(np.asarray(d.dt).ravel()[0])
            if not np.isfinite(dt) or dt <= 0:
                raise FormatError(
                    p, f"dt must be a positive number of seconds, got {dt}", where=where
                )
            arms = _arms(d.X, p, where)
            n = arms[0].pos.shape[0]
            name = str(getattr(d, "name", "")) or f"{p.name}[{i}]"
            out.append(
                LabelledStream(
                    name,
                    np.arange(n, dtype=np.float64) * dt,
                    arms,
                    _labels(lab, n, p, f"True_states[{i}]"),
                )
            )
        return out
    data_keys = sorted(k for k in m if k.startswith("Data"))
    for key in data_keys:
        suffix = key[len("Data") :]
        lab_key = f"True_states{suffix}"
        if lab_key not in m:
            continue
        rate = DEFAULT_RATE_HZ if rate_hz is None else float(rate_hz)
        if not np.isfinite(rate) or rate <= 0:
            raise FormatError(p, f"rate must be a positive number of Hz, got {rate}")
        streams, labs = _cells(m[key]), _cells(m[lab_key])
        if len(streams) != len(labs):
            raise FormatError(p, f"{len(streams)} {key} elements but {len(labs)} {lab_key}")
        out = []
        for i, (x, lab) in enumerate(zip(streams, labs, strict=True)):
            arms = _arms(x, p, f"{key}[{i}]")
            n = arms[0].pos.shape[0]
            out.append(
                LabelledStream(
                    f"{p.name}[{i}]",
                    np.arange(n) / rate,
                    arms,
                    _labels(lab, n, p, f"{lab_key}[{i}]"),
                    rate_assumed=rate_hz is None,
                )
            )
        return out
    found = ", ".join(sorted(m)) or "none"
    raise FormatError(
        p,
        "expected proc_data + True_states or Data_<x> + True_states_<x> "
        f"(labelled demonstrations); variables found: {found}",
    )
