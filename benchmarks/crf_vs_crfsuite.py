"""thirdhand's pair CRF against CRFsuite (python-crfsuite) on the same features and labels.

Both get the same design rows (bias + four log-variance features per latent
step, float-valued attributes) and the same labels, from noisy synthetic
pick-and-place scenes (train and test seeds disjoint), and the same L2 penalty
(thirdhand minimises ``NLL + ½ λ ||θ||²``, CRFsuite ``NLL + c2 ||θ||²``.
CRFsuite keeps a state weight per label, ``w₀ = −w₁ = δ/2`` at the optimum, so
its penalty on a state weight difference ``δ`` is ``c2 δ²/2``: ``c2 = λ`` (the
default) matches thirdhand's state penalty exactly and doubles the one on the
four transition weights; ``--c2-factor 0.5`` matches the transitions instead
and halves the state penalty.) CRFsuite gets every possible
state and transition feature (``feature.minfreq=0``, ``possible_states``,
``possible_transitions``); the
log features are passed negated (see :func:`items`).

Printed: training time of each and their ratio; on the test set, the sequence
NLL ``−Σ log p(y | x)`` (CRFsuite's from ``Tagger.probability``), the
marginal NLL ``−Σ_t log p(y_t | x)`` (from ``Tagger.marginal``) and Viterbi
accuracy. Target: thirdhand ≤ 0.5× CRFsuite's training time at equal or better
test NLL.

Usage: ``python benchmarks/crf_vs_crfsuite.py [--train 8] [--test 4] [--duration 60]``
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np
import pycrfsuite

from thirdhand.datasets.pick_place import random_pick_place_demo
from thirdhand.segment.crf import PairCRF
from thirdhand.segment.design import FeatureConfig
from thirdhand.segment.training import labelled_sequences


def sequences(seeds: range, duration: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    demos = [
        random_pick_place_demo(
            np.random.default_rng(s),
            n_parts=4,
            duration=duration,
            hands=("left", "right"),
            noise_pos=5e-4,
            noise_rot=5e-3,
            missing=0.2,
        )
        for s in seeds
    ]
    data = labelled_sequences(demos, FeatureConfig())
    return data.xs, data.ys


def items(x: np.ndarray, names: list[str]) -> list[dict[str, float]]:
    """CRFsuite items: the design row with the log features negated.

    CRFsuite counts a feature's frequency as the sum of its attribute values and
    drops features whose frequency is below ``feature.minfreq`` (0): the
    log-variances are all negative and would vanish. Negated, they are positive;
    the model is the same (the weight changes sign, the L2 penalty does not).
    """
    sign = np.ones(x.shape[1])
    sign[1:] = -1.0
    return [{n: float(v) for n, v in zip(names, row * sign, strict=True)} for row in x]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--train", type=int, default=8, help="training scenes")
    ap.add_argument("--test", type=int, default=4, help="test scenes")
    ap.add_argument("--duration", type=float, default=60.0, help="seconds per scene")
    ap.add_argument("--l2", type=float, default=1.0, help="L2 penalty λ")
    ap.add_argument(
        "--c2-factor", type=float, default=1.0, help="CRFsuite c2 = factor × λ (see above)"
    )
    args = ap.parse_args()

    xs, ys = sequences(range(args.train), args.duration)
    xt, yt = sequences(range(1000, 1000 + args.test), args.duration)
    names = FeatureConfig().feature_names
    n_train = sum(len(y) for y in ys)
    n_test = sum(len(y) for y in yt)
    print(f"train: {len(xs)} sequences, {n_train} latent variables; test: {len(xt)}, {n_test}")

    # Warm the numba kernels so compilation is not timed.
    PairCRF(max_iter=2).fit(xs[:1], ys[:1])
    t0 = time.perf_counter()
    crf = PairCRF(l2=args.l2).fit(xs, ys)
    t_ours = time.perf_counter() - t0

    trainer = pycrfsuite.Trainer(algorithm="lbfgs", verbose=False)
    for x, y in zip(xs, ys, strict=True):
        trainer.append(items(x, names), [str(v) for v in y])
    trainer.set_params(
        {
            "c1": 0.0,
            "c2": args.l2 * args.c2_factor,
            "max_iterations": 1000,
            "feature.minfreq": 0,
            "feature.possible_states": True,
            "feature.possible_transitions": True,
        }
    )
    with tempfile.TemporaryDirectory() as tmp:
        model_path = str(Path(tmp) / "crfsuite.model")
        t0 = time.perf_counter()
        trainer.train(model_path)
        t_suite = time.perf_counter() - t0
        tagger = pycrfsuite.Tagger()
        tagger.open(model_path)
        seq_nll = marg_nll = 0.0
        correct = 0
        for x, y in zip(xt, yt, strict=True):
            tagger.set(items(x, names))
            truth = [str(v) for v in y]
            p = tagger.probability(truth)
            seq_nll += -math.log(p) if p > 0 else math.inf
            marg_nll += -sum(
                math.log(max(tagger.marginal(lab, i), 1e-300)) for i, lab in enumerate(truth)
            )
            correct += sum(a == b for a, b in zip(tagger.tag(), truth, strict=True))
        tagger.close()

    ours_seq = crf.nll(xt, yt)
    probs = crf.predict_proba(xt)
    ours_marg = -sum(
        float(np.sum(np.log(np.maximum(np.where(y == 1, p, 1.0 - p), 1e-300))))
        for p, y in zip(probs, yt, strict=True)
    )
    ours_acc = float(np.mean(np.concatenate(crf.predict(xt)) == np.concatenate(yt)))

    print(f"{'':12s} {'train s':>9s} {'test NLL':>10s} {'/var':>8s} {'marg. NLL':>10s} {'acc':>7s}")
    print(
        f"{'thirdhand':12s} {t_ours:9.3f} {ours_seq:10.2f} {ours_seq / n_test:8.4f} "
        f"{ours_marg:10.2f} {ours_acc:7.4f}"
    )
    print(
        f"{'CRFsuite':12s} {t_suite:9.3f} {seq_nll:10.2f} {seq_nll / n_test:8.4f} "
        f"{marg_nll:10.2f} {correct / n_test:7.4f}"
    )
    print(
        f"training time ratio thirdhand / CRFsuite: {t_ours / t_suite:.3f} "
        f"(target <= 0.5); test NLL ratio: {ours_seq / seq_nll:.3f} (target <= 1)"
    )


if __name__ == "__main__":
    main()
