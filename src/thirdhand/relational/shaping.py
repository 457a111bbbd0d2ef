"""Reward shaping for RCSI: ``q'(s,a) = q(s,a) + f(s)`` keeps the greedy policy.

``f(s) = w · φ(s)`` with relational state features φ (counts of true atoms per
predicate, and of binary atoms whose first or second argument satisfies a unary
predicate, divided by the number of objects, so they transfer across sizes); the
weights w are chosen by CMA-ES (the ``cma`` package) to minimise the entropy of
the regression targets ``r̂ + f(s) − γ f(s')`` binned at a fixed width, so that
the reward tree has fewer distinct values to fit.
"""

from __future__ import annotations

import cma
import numpy as np
from numpy.typing import NDArray

from thirdhand.relational.mdp import GroundMDP


def feature_names(mdp: GroundMDP) -> list[str]:
    """Names of the features of :func:`state_features`."""
    preds = sorted(mdp.domain.predicates.items())
    names = [f"#{p}" for p, k in preds if k >= 1]
    unary = [p for p, k in preds if k == 1]
    for p, k in preds:
        if k == 2:
            names += [f"#{p}(X,Y),{u}(X)" for u in unary] + [f"#{p}(X,Y),{u}(Y)" for u in unary]
    return names


def state_features(mdp: GroundMDP, states: NDArray[np.int64]) -> NDArray[np.float64]:
    """Relational count features φ(s), shape (n, n_features), divided by the number of objects."""
    s = np.asarray(states)
    preds = sorted(mdp.domain.predicates.items())
    n_obj = len(mdp.domain.objects)
    cols = [mdp.tables[p][s].reshape(s.size, -1).sum(axis=1) for p, k in preds if k >= 1]
    unary = [p for p, k in preds if k == 1]
    for p, k in preds:
        if k == 2:
            t = mdp.tables[p][s].astype(np.float64)
            cols += [np.einsum("nxy,nx->n", t, mdp.tables[u][s]) for u in unary]
            cols += [np.einsum("nxy,ny->n", t, mdp.tables[u][s]) for u in unary]
    return np.stack(cols, axis=1).astype(np.float64) / n_obj


def binned_entropy(
    values: NDArray[np.float64], width: float, weights: NDArray[np.float64] | None = None
) -> float:
    """Shannon entropy (nats) of ``values`` binned at ``width`` (optionally weighted)."""
    _, inv = np.unique(np.round(values / width), return_inverse=True)
    counts = np.bincount(inv.ravel(), weights=weights)
    p = counts[counts > 0] / counts.sum()
    return float(-(p * np.log(p)).sum())


def fit_shaping(
    phi_s: NDArray[np.float64],
    phi_next: NDArray[np.float64],
    targets: NDArray[np.float64],
    gamma: float,
    *,
    weights: NDArray[np.float64] | None = None,
    seed: int = 0,
    max_evals: int = 600,
) -> NDArray[np.float64]:
    """Weights w minimising the binned entropy of ``targets + φ(s)·w − γ φ(s')·w``.

    Parameters
    ----------
    phi_s, phi_next : ndarray, shape (n, d)
        Features of the states and successor states of the transitions.
    targets : ndarray, shape (n,)
        Unshaped regression targets r̂.
    weights : ndarray, shape (n,), optional
        Sample weights of the entropy.

    Returns
    -------
    ndarray, shape (d,)
        Shaping weights (zeros if CMA-ES finds nothing better).
    """
    diff = phi_s - gamma * phi_next
    width = max(float(np.std(targets)) / 8.0, 1e-6)
    base = binned_entropy(targets, width, weights)

    def cost(w: NDArray[np.float64]) -> float:
        return binned_entropy(targets + diff @ w, width, weights)

    es = cma.CMAEvolutionStrategy(
        np.zeros(diff.shape[1]),
        float(np.std(targets)) + 1e-3,
        {"seed": seed + 1, "maxfevals": max_evals, "verbose": -9, "tolfun": 1e-9},
    )
    while not es.stop():
        xs = es.ask()
        es.tell(xs, [cost(np.asarray(x)) for x in xs])
    w = np.asarray(es.result.xbest)
    return w if cost(w) < base else np.zeros(diff.shape[1])
