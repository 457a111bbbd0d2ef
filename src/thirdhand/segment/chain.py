"""Dynamic programs of a linear chain: forward–backward (log space) and Viterbi.

A chain of ``n`` steps and ``s`` states is scored by unary potentials
``u[t, a]`` and a transition matrix ``T[a, b]`` for ``y_t = a`` after
``y_{t-1} = b``:

``score(y) = Σ_t u[t, y_t] + Σ_{t≥1} T[y_t, y_{t-1}]``, ``p(y) = exp(score(y) − log Z)``.

Several chains are processed at once from a concatenated unary array and
offsets; every kernel is compiled with numba.
"""

from __future__ import annotations

import numba
import numpy as np

from thirdhand.arrays import FloatArray, IntArray


@numba.njit(cache=True, nogil=True)
def _lse_row(v: FloatArray) -> float:  # pragma: no cover - compiled
    m = v.max()
    if m == -np.inf:
        return -np.inf
    s = 0.0
    for x in v:
        s += np.exp(x - m)
    return m + np.log(s)


@numba.njit(cache=True, nogil=True)
def _forward_backward(  # pragma: no cover - compiled
    unary: FloatArray, trans: FloatArray, offsets: IntArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    n, s = unary.shape
    n_seq = offsets.size - 1
    log_z = np.zeros(n_seq)
    marg = np.zeros((n, s))
    pair_sum = np.zeros((s, s))
    alpha = np.empty((n, s))
    beta = np.empty((n, s))
    tmp = np.empty(s)
    for q in range(n_seq):
        lo = offsets[q]
        hi = offsets[q + 1]
        if hi <= lo:
            continue
        for a in range(s):
            alpha[lo, a] = unary[lo, a]
        for t in range(lo + 1, hi):
            for a in range(s):
                for b in range(s):
                    tmp[b] = alpha[t - 1, b] + trans[a, b]
                alpha[t, a] = unary[t, a] + _lse_row(tmp)
        lz = _lse_row(alpha[hi - 1])
        log_z[q] = lz
        for a in range(s):
            beta[hi - 1, a] = 0.0
        for t in range(hi - 2, lo - 1, -1):
            for b in range(s):
                for a in range(s):
                    tmp[a] = trans[a, b] + unary[t + 1, a] + beta[t + 1, a]
                beta[t, b] = _lse_row(tmp)
        for t in range(lo, hi):
            for a in range(s):
                marg[t, a] = np.exp(alpha[t, a] + beta[t, a] - lz)
            if t > lo:
                for a in range(s):
                    for b in range(s):
                        pair_sum[a, b] += np.exp(
                            alpha[t - 1, b] + trans[a, b] + unary[t, a] + beta[t, a] - lz
                        )
    return log_z, marg, pair_sum


@numba.njit(cache=True, nogil=True)
def _pairwise(  # pragma: no cover - compiled
    unary: FloatArray, trans: FloatArray
) -> FloatArray:
    n, s = unary.shape
    out = np.zeros((max(n - 1, 0), s, s))
    if n < 2:
        return out
    alpha = np.empty((n, s))
    beta = np.empty((n, s))
    tmp = np.empty(s)
    for a in range(s):
        alpha[0, a] = unary[0, a]
    for t in range(1, n):
        for a in range(s):
            for b in range(s):
                tmp[b] = alpha[t - 1, b] + trans[a, b]
            alpha[t, a] = unary[t, a] + _lse_row(tmp)
    lz = _lse_row(alpha[n - 1])
    for a in range(s):
        beta[n - 1, a] = 0.0
    for t in range(n - 2, -1, -1):
        for b in range(s):
            for a in range(s):
                tmp[a] = trans[a, b] + unary[t + 1, a] + beta[t + 1, a]
            beta[t, b] = _lse_row(tmp)
    for t in range(1, n):
        for a in range(s):
            for b in range(s):
                out[t - 1, a, b] = np.exp(
                    alpha[t - 1, b] + trans[a, b] + unary[t, a] + beta[t, a] - lz
                )
    return out


@numba.njit(cache=True, nogil=True)
def _viterbi(  # pragma: no cover - compiled
    unary: FloatArray, trans: FloatArray, offsets: IntArray
) -> tuple[IntArray, FloatArray]:
    n, s = unary.shape
    n_seq = offsets.size - 1
    path = np.zeros(n, dtype=np.int64)
    best = np.zeros(n_seq)
    delta = np.empty((n, s))
    back = np.zeros((n, s), dtype=np.int64)
    for q in range(n_seq):
        lo = offsets[q]
        hi = offsets[q + 1]
        if hi <= lo:
            continue
        for a in range(s):
            delta[lo, a] = unary[lo, a]
        for t in range(lo + 1, hi):
            for a in range(s):
                bi = 0
                bv = delta[t - 1, 0] + trans[a, 0]
                for b in range(1, s):
                    v = delta[t - 1, b] + trans[a, b]
                    if v > bv:
                        bv = v
                        bi = b
                delta[t, a] = unary[t, a] + bv
                back[t, a] = bi
        k = 0
        for a in range(1, s):
            if delta[hi - 1, a] > delta[hi - 1, k]:
                k = a
        best[q] = delta[hi - 1, k]
        path[hi - 1] = k
        for t in range(hi - 1, lo, -1):
            k = back[t, k]
            path[t - 1] = k
    return path, best


def _offsets(offsets: IntArray | None, n: int) -> IntArray:
    if offsets is None:
        return np.array([0, n], dtype=np.int64)
    return np.ascontiguousarray(offsets, dtype=np.int64)


def forward_backward(
    unary: FloatArray, trans: FloatArray, offsets: IntArray | None = None
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Log partition functions, marginals and summed pairwise marginals.

    Parameters
    ----------
    unary : ndarray, shape (n, s)
        Unary log-potentials of all chains, concatenated.
    trans : ndarray, shape (s, s)
        ``trans[a, b]``: log-potential of ``y_t = a`` after ``y_{t-1} = b``.
    offsets : ndarray of int, shape (n_chains + 1,), optional
        Chain ``i`` covers rows ``offsets[i]:offsets[i + 1]``; one chain by default.

    Returns
    -------
    log_z : ndarray, shape (n_chains,)
    marginals : ndarray, shape (n, s)
        ``p(y_t = a | x)``.
    pair_sum : ndarray, shape (s, s)
        ``Σ_t p(y_t = a, y_{t-1} = b | x)`` over every chain's steps ``t ≥ 1``.
    """
    u = np.ascontiguousarray(unary, dtype=np.float64)
    return _forward_backward(u, np.ascontiguousarray(trans, np.float64), _offsets(offsets, len(u)))


def pairwise_marginals(unary: FloatArray, trans: FloatArray) -> FloatArray:
    """Pairwise marginals of one chain, shape (n − 1, s, s): ``p(y_t = a, y_{t-1} = b)``.

    Row ``i`` is step ``t = i + 1``.
    """
    return _pairwise(
        np.ascontiguousarray(unary, np.float64), np.ascontiguousarray(trans, np.float64)
    )


def viterbi(
    unary: FloatArray, trans: FloatArray, offsets: IntArray | None = None
) -> tuple[IntArray, FloatArray]:
    """Most probable labelling of every chain.

    Parameters
    ----------
    unary : ndarray, shape (n, s)
    trans : ndarray, shape (s, s)
    offsets : ndarray of int, shape (n_chains + 1,), optional

    Returns
    -------
    path : ndarray of int, shape (n,)
    score : ndarray, shape (n_chains,)
        Unnormalised log-score of each chain's best path.
    """
    u = np.ascontiguousarray(unary, dtype=np.float64)
    return _viterbi(u, np.ascontiguousarray(trans, np.float64), _offsets(offsets, len(u)))


@numba.njit(cache=True, nogil=True)
def _binary_scaled(  # pragma: no cover - compiled
    score1: FloatArray, offsets: IntArray, trans: FloatArray, e_trans: FloatArray
) -> tuple[float, FloatArray, bool]:
    """Scaled forward–backward of binary chains with unary potentials ``(0, score1[t])``.

    Each step's potentials are shifted by their maximum before exponentiation and
    every forward/backward vector is normalised, so nothing overflows; shifts and
    normalisers are added back in log space. The one kernel behind prediction
    (:func:`binary_marginals`) and training (:func:`binary_expectations`).

    Parameters
    ----------
    score1 : ndarray, shape (n,)
    offsets : ndarray of int, shape (n_chains + 1,)
    trans : ndarray, shape (2, 2)
    e_trans : ndarray, shape (2, 2)
        Receives ``Σ_{t≥1} p(y_t = a, y_{t-1} = b | x)`` (added to it); pass a
        shape (0, 0) array to skip the pairwise marginals.

    Returns
    -------
    log_z : float
        ``Σ_chains log Z``.
    marg : ndarray, shape (n,)
        ``p(y_t = 1 | x)``.
    ok : bool
        False when a normaliser underflowed to zero (transition weights beyond
        about ±700): the caller falls back to the log-space recursions.
    """
    n = score1.size
    pairs = e_trans.size == 4
    tmax = max(max(trans[0, 0], trans[0, 1]), max(trans[1, 0], trans[1, 1]))
    m00 = np.exp(trans[0, 0] - tmax)
    m01 = np.exp(trans[0, 1] - tmax)
    m10 = np.exp(trans[1, 0] - tmax)
    m11 = np.exp(trans[1, 1] - tmax)
    a0 = np.empty(n)
    a1 = np.empty(n)
    p0 = np.empty(n)
    p1 = np.empty(n)
    marg = np.empty(n)
    log_z = 0.0
    ok = True
    for q in range(offsets.size - 1):
        lo = offsets[q]
        hi = offsets[q + 1]
        if hi <= lo:
            continue
        # Product of normalisers, flushed into log_z before it can underflow.
        prod = 1.0
        log_z += tmax * (hi - lo - 1)
        for t in range(lo, hi):
            u = score1[t]
            if u > 0.0:
                e0 = np.exp(-u)
                e1 = 1.0
                log_z += u
            else:
                e0 = 1.0
                e1 = np.exp(u)
            p0[t] = e0
            p1[t] = e1
            if t == lo:
                f0 = e0
                f1 = e1
            else:
                f0 = e0 * (m00 * a0[t - 1] + m01 * a1[t - 1])
                f1 = e1 * (m10 * a0[t - 1] + m11 * a1[t - 1])
            c = f0 + f1
            if not c > 0.0:
                ok = False
                c = 1.0
            a0[t] = f0 / c
            a1[t] = f1 / c
            prod *= c
            if prod < 1e-200:
                log_z += np.log(prod)
                prod = 1.0
        log_z += np.log(prod)
        b0 = 1.0
        b1 = 1.0
        for t in range(hi - 1, lo - 1, -1):
            mz = a0[t] * b0 + a1[t] * b1
            if not mz > 0.0:
                ok = False
                mz = 1.0
            marg[t] = a1[t] * b1 / mz
            if t > lo:
                r0 = p0[t] * b0
                r1 = p1[t] * b1
                if pairs:
                    # p(y_t = a, y_{t-1} = b) ∝ alpha_{t-1}(b) M(a, b) psi_t(a) beta_t(a)
                    s00 = a0[t - 1] * m00 * r0
                    s01 = a1[t - 1] * m01 * r0
                    s10 = a0[t - 1] * m10 * r1
                    s11 = a1[t - 1] * m11 * r1
                    sz = s00 + s01 + s10 + s11
                    if not sz > 0.0:
                        ok = False
                        sz = 1.0
                    e_trans[0, 0] += s00 / sz
                    e_trans[0, 1] += s01 / sz
                    e_trans[1, 0] += s10 / sz
                    e_trans[1, 1] += s11 / sz
                nb0 = m00 * r0 + m10 * r1
                nb1 = m01 * r0 + m11 * r1
                bz = nb0 + nb1
                if not bz > 0.0:
                    ok = False
                    bz = 1.0
                b0 = nb0 / bz
                b1 = nb1 / bz
    return log_z, marg, ok


def binary_marginals(score1: FloatArray, trans: FloatArray, offsets: IntArray) -> FloatArray:
    """``p(y_t = 1 | x)`` of binary chains with unary potentials ``(0, score1[t])``.

    Parameters
    ----------
    score1 : ndarray, shape (n,)
        Unary log-potential of ``y_t = 1`` (that of ``y_t = 0`` is 0), all chains.
    trans : ndarray, shape (2, 2)
    offsets : ndarray of int, shape (n_chains + 1,)

    Returns
    -------
    ndarray, shape (n,)
    """
    sc = np.ascontiguousarray(score1, np.float64)
    tc = np.ascontiguousarray(trans, np.float64)
    oc = np.ascontiguousarray(offsets, np.int64)
    if float(np.ptp(tc)) < 600.0:
        _, marg, ok = _binary_scaled(sc, oc, tc, np.empty((0, 0)))
        if ok:
            return marg
    u = np.zeros((sc.size, 2))
    u[:, 1] = sc
    return forward_backward(u, tc, oc)[1][:, 1]


def binary_expectations(
    x: FloatArray, offsets: IntArray, w: FloatArray, trans: FloatArray
) -> tuple[float, FloatArray, FloatArray]:
    """Log partition function and expected features of a binary chain CRF.

    Parameters
    ----------
    x : ndarray, shape (n, d)
        State features of all chains, concatenated; the unary potential of
        ``y_t = 1`` is ``x_t·w`` and of ``y_t = 0`` is 0.
    offsets : ndarray of int, shape (n_chains + 1,)
    w : ndarray, shape (d,)
    trans : ndarray, shape (2, 2)
        ``trans[a, b]`` weighs ``y_t = a`` after ``y_{t-1} = b``.

    Returns
    -------
    log_z : float
        ``Σ_chains log Z``.
    e_state : ndarray, shape (d,)
        ``Σ_t p(y_t = 1 | x) x_t``.
    e_trans : ndarray, shape (2, 2)
        ``Σ_{t≥1} p(y_t = a, y_{t-1} = b | x)``.
    """
    xc = np.ascontiguousarray(x, np.float64)
    tc = np.ascontiguousarray(trans, np.float64)
    oc = np.ascontiguousarray(offsets, np.int64)
    # Transition weights spread by more than ~600 make exp() of the shifted weights
    # subnormal, losing relative precision: those take the log-space recursions.
    if float(np.ptp(tc)) < 600.0:
        e_t = np.zeros((2, 2))
        log_z, marg1, ok = _binary_scaled(xc @ np.asarray(w, np.float64), oc, tc, e_t)
        if ok:
            return log_z, marg1 @ xc, e_t
    u = np.zeros((len(xc), 2))
    u[:, 1] = xc @ w
    lz, marg, pair_sum = forward_backward(u, tc, oc)
    return float(lz.sum()), marg[:, 1] @ xc, pair_sum


__all__ = [
    "binary_expectations",
    "binary_marginals",
    "forward_backward",
    "pairwise_marginals",
    "viterbi",
]
