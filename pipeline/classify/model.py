"""The track classifier at run time: a verified model file and fast inference (SR-CLS-1, -3).

The model is an XGBoost ``multi:softprob`` booster (depth 6, 150 rounds by default) trained by
``safecase train`` (:mod:`pipeline.training.train`) and committed as XGBoost's JSON model file
``pipeline/models/classifier.json`` with a card beside it (``classifier.card.json``: the
file's SHA-256, the class and feature names, the XGBoost version and a description of the
training data). Loading checks the file's SHA-256 against the expected one (the configured
``classify.model_sha256``, else the card's) and refuses a mismatch with
:class:`ModelHashError`: the model in use is always the one whose hash the evidence and the
audit log record (:attr:`Classifier.model_sha256`). Inference evaluates the trees in numpy
(:mod:`pipeline.classify.trees`); XGBoost itself is only the oracle and the trainer.

Every load reads and hashes the file; parsing it (about a second of CPU for the packaged model)
is done once per thread and model hash, so the classifiers a thread makes share one parsed
ensemble (it holds scratch buffers: use a classifier from the thread that made it).
"""

from __future__ import annotations

import hashlib
import json
import threading
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from pipeline.classify.trees import ModelFormatError, TreeEnsemble
from pipeline.config import ClassifySection
from pipeline.errors import SafecaseError
from pipeline.features import FEATURE_NAMES
from pipeline.types import Classification, FloatArray, TrackFeatures, TrackStatus

__all__ = [
    "FORKLIFT_CLASSES",
    "MODEL_CLASSES",
    "MOVING_CLASSES",
    "NEAR_REVERSAL_CLASS",
    "PACKAGED_MODEL",
    "PERSON_CLASS",
    "SCORED_STATUSES",
    "STILL_CLASSES",
    "Classifier",
    "ModelError",
    "ModelFormatError",
    "ModelHashError",
    "card_path",
    "file_sha256",
    "model_provenance",
    "packaged_model_sha256",
    "unscored",
]

PACKAGED_MODEL = Path(__file__).resolve().parents[1] / "models" / "classifier.json"

# The classes ``safecase train`` trains (a loaded model's card is authoritative). Other wheeled
# traffic (AMRs, baggage tugs, dollies) is one class, "vehicle": every one of them gets the
# same prediction (a moving cone) and closing speed (its own speed bound), and 8 classes keep
# inference within budget (one tree per class per round).
MODEL_CLASSES: tuple[str, ...] = (
    "forklift_moving",
    "forklift_stationary",
    "forklift_near_reversal",
    "pallet_jack",
    "cart",
    "person",
    "vehicle",
    "static",
)
# Class names with a meaning downstream (prediction mode, margin, closing speed).
NEAR_REVERSAL_CLASS = "forklift_near_reversal"
PERSON_CLASS = "person"
FORKLIFT_CLASSES = frozenset({"forklift_moving", "forklift_stationary", NEAR_REVERSAL_CLASS})
STILL_CLASSES = frozenset({"forklift_stationary", "cart", "static"})
MOVING_CLASSES = frozenset({"forklift_moving", "pallet_jack", PERSON_CLASS, "vehicle"})
# Tracks the classifier scores: confirmed ones and lost ones (still predicted); a tentative
# track is too young to trust and a dormant one is not observed.
SCORED_STATUSES = (TrackStatus.CONFIRMED, TrackStatus.LOST)
_FLOAT32_MAX = float(np.finfo(np.float32).max)


class ModelError(SafecaseError, ValueError):
    """A classifier model that cannot be used: missing, unreadable or inconsistent."""


class ModelHashError(ModelError):
    """The model file's SHA-256 differs from the expected one (SR-CLS-3)."""


# Parsed ensembles of this thread by model SHA-256, oldest first; a few models at most (a test
# session trains and loads small ones beside the packaged model).
_PARSED = threading.local()
_PARSED_PER_THREAD = 4


def _parsed(data: bytes, sha256: str) -> TreeEnsemble:
    """The ensemble of model file content ``data`` (whose SHA-256 ``sha256`` the caller has just
    computed and verified), parsed once per thread."""
    cache: dict[str, TreeEnsemble] = _PARSED.__dict__.setdefault("by_sha256", {})
    ensemble = cache.get(sha256)
    if ensemble is None:
        ensemble = TreeEnsemble.from_json(data)
        if len(cache) >= _PARSED_PER_THREAD:
            del cache[next(iter(cache))]
        cache[sha256] = ensemble
    return ensemble


def file_sha256(path: Path) -> str:
    """SHA-256 (hex) of a file's bytes."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def card_path(model_path: Path) -> Path:
    """The card that describes ``model_path`` (``x.json`` -> ``x.card.json``)."""
    return model_path.with_name(model_path.stem + ".card.json")


def _read_card(model_path: Path) -> dict[str, Any]:
    path = card_path(model_path)
    try:
        card = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ModelError(f"model card {path}: cannot read it ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise ModelError(f"model card {path}: not valid JSON ({exc})") from None
    for key in ("model_sha256", "class_names", "feature_names"):
        if key not in card:
            raise ModelError(f"model card {path}: missing key {key!r}")
    return dict(card)


def model_provenance(section: ClassifySection) -> dict[str, Any]:
    """What the evidence and the audit log record about the configured model (SR-CLS-3).

    The file's actual SHA-256 (not only its card's claim), the card's record, the pinned hash
    if configured, and whether they agree. Never raises: a missing file or card is recorded as
    such (the classifier itself refuses to load then).
    """
    path = Path(section.model_path) if section.model_path else PACKAGED_MODEL
    out: dict[str, Any] = {"path": str(path), "pinned_sha256": section.model_sha256 or None}
    try:
        out["sha256"] = file_sha256(path)
    except OSError as exc:
        out["sha256"] = None
        out["error"] = f"cannot read the model file: {exc.strerror}"
        return out
    try:
        card = _read_card(path)
    except ModelError as exc:
        out["card_sha256"] = None
        out["error"] = str(exc)
        return out
    out["card_sha256"] = card["model_sha256"]
    out["xgboost_version"] = card.get("xgboost_version")
    expected = (section.model_sha256 or str(card["model_sha256"])).lower()
    out["verified"] = out["sha256"] == expected
    return out


def packaged_model_sha256() -> str:
    """SHA-256 of the packaged model file as its card records it (no loading, no xgboost)."""
    return str(_read_card(PACKAGED_MODEL)["model_sha256"])


class Classifier:
    """A loaded, hash-verified classifier (SR-CLS-1, SR-CLS-3).

    ``model_path`` defaults to the packaged model; ``expected_sha256`` (hex) to the card's
    record. Raises :class:`ModelHashError` when the file's hash differs, :class:`ModelError`
    when the file or its card is missing or inconsistent (feature names, class count). The
    file is read and hashed on every load; the parsed trees are shared by the classifiers of
    one thread (module docstring).
    """

    def __init__(self, model_path: Path | None = None, expected_sha256: str = "") -> None:
        path = PACKAGED_MODEL if model_path is None else Path(model_path)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise ModelError(f"classifier model {path}: cannot read it ({exc.strerror})") from None
        self.model_path = path
        self.model_sha256 = hashlib.sha256(data).hexdigest()
        self.card = _read_card(path)
        expected = (expected_sha256 or str(self.card["model_sha256"])).strip().lower()
        if self.model_sha256 != expected:
            raise ModelHashError(
                f"classifier model {path}: SHA-256 {self.model_sha256}, expected {expected} "
                "(the model file changed since it was recorded; retrain or restore it)"
            )
        names = tuple(str(n) for n in self.card["feature_names"])
        if names != FEATURE_NAMES:
            raise ModelError(
                f"classifier model {path}: trained on features {names}; this pipeline computes "
                f"{FEATURE_NAMES}"
            )
        try:
            self.ensemble = _parsed(data, self.model_sha256)
        except ModelFormatError as exc:
            raise ModelError(f"classifier model {path}: {exc}") from None
        self.class_names: tuple[str, ...] = tuple(str(c) for c in self.card["class_names"])
        if len(self.class_names) != self.ensemble.n_classes:
            raise ModelError(
                f"classifier model {path}: card lists {len(self.class_names)} classes, the model "
                f"has {self.ensemble.n_classes}"
            )
        self.rows_rejected = 0
        if self.ensemble.n_features != len(FEATURE_NAMES):
            raise ModelError(
                f"classifier model {path}: {self.ensemble.n_features} features, expected "
                f"{len(FEATURE_NAMES)}"
            )

    @classmethod
    def from_config(cls, section: ClassifySection) -> Classifier:
        """The classifier configured in the ``classify`` section."""
        path = Path(section.model_path) if section.model_path else None
        return cls(path, section.model_sha256)

    def class_index(self, name: str) -> int:
        """Output column of the class called ``name``, or -1 when the model has no such class."""
        return self.class_names.index(name) if name in self.class_names else -1

    def probabilities(self, values: npt.ArrayLike) -> FloatArray:
        """Class probabilities (n, C) of feature rows (n, 10); NaN = missing (SR-CLS-1)."""
        return self.ensemble.probabilities(values)

    def classify(self, features: TrackFeatures) -> Classification:
        """Score the confirmed and lost tracks; others get class -1 and confidence 0.

        A row with an infinite value, or one beyond float32 range (the model's input
        precision), is not scored either (the tracker never produces one; if it did, the
        track gets the cautious fallback) and counted in :attr:`rows_rejected`.
        """
        scored = np.isin(features.status, [int(s) for s in SCORED_STATUSES])
        values = features.values
        bad = (np.abs(values) > _FLOAT32_MAX).any(axis=1)  # NaN compares False: stays
        self.rows_rejected += int(np.count_nonzero(scored & bad))
        scored &= ~bad
        n, c = features.n, len(self.class_names)
        probability = np.full((n, c), np.nan)
        index = np.full(n, -1, dtype=np.int64)
        confidence = np.zeros(n)
        if scored.any():
            p = self.ensemble.probabilities(values[scored])
            probability[scored] = p
            best = p.argmax(axis=1)
            index[scored] = best
            confidence[scored] = p[np.arange(p.shape[0]), best]
        return Classification(
            stamp_s=features.stamp_s,
            track_id=features.track_id,
            class_index=index,
            probability=probability,
            confidence=confidence,
            class_names=self.class_names,
            model_sha256=self.model_sha256,
        )


def unscored(
    features: TrackFeatures, class_names: tuple[str, ...], model_sha256: str = ""
) -> Classification:
    """Every track unscored (class -1, confidence 0): the fail-safe input to prediction when the
    classifier cannot run; each track then gets the most cautious prediction and margin."""
    n = features.n
    return Classification(
        stamp_s=features.stamp_s,
        track_id=features.track_id,
        class_index=np.full(n, -1, dtype=np.int64),
        probability=np.full((n, len(class_names)), np.nan),
        confidence=np.zeros(n),
        class_names=class_names,
        model_sha256=model_sha256,
    )
