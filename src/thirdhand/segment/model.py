"""The segmentation model as a small JSON document, and the shipped default.

Document (``"format": "thirdhand.segment/1"``)::

    {"format": "thirdhand.segment/1", "version": 1,
     "features": {"latent_rate": 10.0, "window": 5, "transform": "log", ...},
     "feature_names": ["bias", "log_eps_nu_pos", ...],
     "theta": {"transition": [[w00, w01], [w10, w11]], "state": [...]},
     "per_kind": {"part-part": {"transition": ..., "state": ...}, ...},
     "hand": {"min_fingers": 2}, "max_gap_s": 1.0,
     "closure": {"contact_max_m": 0.01}, "rest_gate": true, "training": {...}}

``closure`` is optional (absent or null: part–part labels are the CRF's own).
``rest_gate`` is optional (absent: false): hand/finger–object steps whose object
or finger is at rest, by the recording's own noise floor, are labelled 0
(:mod:`thirdhand.segment.noise`).

``transition[a][b]`` weighs ``y_t = a`` after ``y_{t-1} = b``.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from thirdhand import jsontext
from thirdhand.arrays import FloatArray
from thirdhand.errors import ThirdhandError
from thirdhand.readlimits import check_json_depth, read_input
from thirdhand.segment.assembly import ClosureConfig
from thirdhand.segment.crf import PairCRF
from thirdhand.segment.design import FeatureConfig
from thirdhand.segment.features import SegmentationError

FORMAT = "thirdhand.segment/1"
DEFAULT_MODEL_RESOURCE = "segment_default.json"
#: Models shipped with the package, by name: ``default`` (synthetic scenes plus
#: the real labelled pairs of ``toolbox_coop_4``) and ``synthetic`` (synthetic
#: scenes only), both from ``research/scripts/train_default_segmenter.py``.
BUILTIN_MODELS = {"default": DEFAULT_MODEL_RESOURCE, "synthetic": "segment_synthetic.json"}


class ModelFileError(ThirdhandError, ValueError):
    """A segmentation model file is missing or malformed."""


@dataclass
class SegmentModel:
    """Everything needed to segment a demonstration.

    Attributes
    ----------
    features : FeatureConfig
    coef_transition : ndarray, shape (2, 2)
    coef_state : ndarray, shape (n_features,)
        Weights of :attr:`FeatureConfig.feature_names`.
    min_fingers : int
        Fingers that must interact for their hand to interact.
    max_gap_s : float
        Runs of steps without evidence longer than this, seconds, are labelled 0
        (probability unknown) instead of being bridged by the chain.
    training : dict
        Free-form provenance (data set, seeds, penalty, scores).
    per_kind : dict kind -> (transition (2, 2), state (n_features,))
        Optional weights for one pair kind (``"finger-object"``, ``"tool-part"``,
        ``"part-part"``...), used instead of the shared ones for pairs of that kind.
    closure : ClosureConfig or None
        When set, part–part labels of parts whose boxes are apart come from the
        assembly closure (:mod:`thirdhand.segment.assembly`).
    rest_gate : bool
        Label 0 (probability 0) every hand/finger–object step at which the
        object or the finger shows no motion beyond its noise floor
        (:mod:`thirdhand.segment.noise`).
    """

    features: FeatureConfig
    coef_transition: FloatArray
    coef_state: FloatArray
    min_fingers: int = 2
    max_gap_s: float = 1.0
    training: dict[str, Any] = field(default_factory=dict)
    per_kind: dict[str, tuple[FloatArray, FloatArray]] = field(default_factory=dict)
    closure: ClosureConfig | None = None
    rest_gate: bool = False

    @classmethod
    def from_crf(cls, crf: PairCRF, features: FeatureConfig, **kwargs: Any) -> SegmentModel:
        """Wrap a fitted :class:`PairCRF`."""
        return cls(features, crf.coef_transition_.copy(), crf.coef_state_.copy(), **kwargs)

    def crf(self, kind: str | None = None) -> PairCRF:
        """A :class:`PairCRF` holding the weights of pair kind ``kind`` (shared by default).

        A hand–object pair without weights of its own uses the finger–object ones.
        """
        if kind == "hand-object" and kind not in self.per_kind:
            kind = "finger-object"
        trans, state = self.per_kind.get(kind or "", (self.coef_transition, self.coef_state))
        return PairCRF().set_params_theta(np.concatenate([trans.ravel(), state]))

    def to_dict(self) -> dict[str, Any]:
        """JSON-able document."""
        return {
            "format": FORMAT,
            "version": 1,
            "features": self.features.to_dict(),
            "feature_names": self.features.feature_names,
            "theta": {
                "transition": self.coef_transition.tolist(),
                "state": self.coef_state.tolist(),
            },
            "per_kind": {
                k: {"transition": t.tolist(), "state": w.tolist()}
                for k, (t, w) in self.per_kind.items()
            },
            "hand": {"min_fingers": self.min_fingers},
            "max_gap_s": self.max_gap_s,
            "closure": None if self.closure is None else self.closure.to_dict(),
            "rest_gate": self.rest_gate,
            "training": self.training,
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any], *, source: str = "<model>") -> SegmentModel:
        """Inverse of :meth:`to_dict`; raises :class:`ModelFileError` naming ``source``."""
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            got = d.get("format") if isinstance(d, dict) else type(d).__name__
            raise ModelFileError(f"{source}: expected format {FORMAT!r}, got {got!r}")
        try:
            feats = FeatureConfig(**d["features"])
            trans = np.asarray(d["theta"]["transition"], dtype=np.float64)
            state = np.asarray(d["theta"]["state"], dtype=np.float64)
            min_f = int(d.get("hand", {}).get("min_fingers", 2))
            max_gap = float(d.get("max_gap_s", 1.0))
            kinds = {
                str(k): (
                    np.asarray(v["transition"], dtype=np.float64),
                    np.asarray(v["state"], dtype=np.float64),
                )
                for k, v in d.get("per_kind", {}).items()
            }
            closure_d = d.get("closure")
            closure = None if closure_d is None else ClosureConfig(**closure_d)
            rest_gate = d.get("rest_gate", False)
            if not isinstance(rest_gate, bool):
                raise TypeError(f"rest_gate must be true or false, got {rest_gate!r}")
        except (KeyError, TypeError, ValueError, AttributeError, SegmentationError) as exc:
            raise ModelFileError(
                f"{source}: malformed model: {type(exc).__name__}: {exc}"
            ) from None
        n = len(feats.feature_names)
        for where, (t, w) in {"theta": (trans, state), **kinds}.items():
            if t.shape != (2, 2) or w.shape != (n,):
                raise ModelFileError(
                    f"{source} ({where}): expected a 2x2 transition matrix and {n} state "
                    f"weights, got shapes {t.shape} and {w.shape}"
                )
            if not (np.all(np.isfinite(t)) and np.all(np.isfinite(w))):
                raise ModelFileError(f"{source} ({where}): model weights must be finite")
        return cls(
            feats,
            trans,
            state,
            min_f,
            max_gap,
            dict(d.get("training", {})),
            kinds,
            closure,
            rest_gate,
        )

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the JSON document atomically (unique temporary file, then rename; a
        previous file is kept as a numbered backup)."""
        from thirdhand.fileops import write_text

        write_text(path, jsontext.dumps(self.to_dict(), what=str(path), indent=1) + "\n")


def load_model(path: str | os.PathLike[str]) -> SegmentModel:
    """Read a model written by :meth:`SegmentModel.save`."""
    p = Path(path)
    data = read_input(
        p,
        what="segmentation model",
        error=lambda m: ModelFileError(f"{p}: cannot read the model: {m}"),
    )
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise ModelFileError(f"{p}: not a segmentation model (not UTF-8 JSON text)") from None
    check_json_depth(text, error=lambda m: ModelFileError(f"{p}: not a segmentation model: {m}"))
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"{p} line {exc.lineno}: not JSON: {exc.msg}") from None
    return SegmentModel.from_dict(d, source=str(p))


def builtin_model(name: str) -> SegmentModel:
    """A model shipped with the package, by name (:data:`BUILTIN_MODELS`)."""
    if name not in BUILTIN_MODELS:
        raise ModelFileError(
            f"no built-in segmentation model {name!r}; built-in: {', '.join(BUILTIN_MODELS)}"
        )
    resource = BUILTIN_MODELS[name]
    ref = resources.files("thirdhand").joinpath("data", resource)
    try:
        text = ref.read_text()
    except (FileNotFoundError, OSError):
        raise ModelFileError(
            f"the built-in segmentation model {resource} is not installed; "
            "run research/scripts/train_default_segmenter.py or pass a model"
        ) from None
    return SegmentModel.from_dict(json.loads(text), source=resource)


def resolve_model(spec: str | os.PathLike[str] | None) -> SegmentModel:
    """A model from a command line: None (the default), a built-in name, or a model file.

    A name of :data:`BUILTIN_MODELS` is the built-in model unless a file of that
    name exists in the working folder.
    """
    if spec is None:
        return default_model()
    if str(spec) in BUILTIN_MODELS and not Path(spec).exists():
        return builtin_model(str(spec))
    return load_model(spec)


def default_model() -> SegmentModel:
    """The model shipped with the package (synthetic scenes plus real labelled pairs)."""
    return builtin_model("default")


__all__ = [
    "BUILTIN_MODELS",
    "FORMAT",
    "ModelFileError",
    "SegmentModel",
    "builtin_model",
    "default_model",
    "load_model",
    "resolve_model",
]
