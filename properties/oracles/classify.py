"""XGBoost's own prediction as the oracle of the runtime classifier (test-only; SR-CLS-1, -4).

The runtime evaluates the trees itself (:mod:`pipeline.classify.trees`); these adapters load the
same model file into an ``xgboost.Booster`` and predict with XGBoost's two public paths:
``Booster.predict(DMatrix)`` and ``Booster.inplace_predict``. One thread, so that timings are
comparable with the single-threaded runtime and nothing depends on scheduling.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import xgboost as xgb

from pipeline.types import FloatArray

__all__ = [
    "booster",
    "model_thresholds",
    "xgboost_inplace",
    "xgboost_margins",
    "xgboost_probabilities",
]


def booster(model_path: Path) -> Any:
    """The model file loaded by XGBoost itself."""
    b = xgb.Booster()
    b.load_model(str(model_path))
    b.set_param({"nthread": 1})  # timings compare one thread with one thread
    return b


def _matrix(values: npt.ArrayLike) -> Any:
    return xgb.DMatrix(np.asarray(values, dtype=np.float32), missing=np.nan, nthread=1)


def xgboost_probabilities(b: Any, values: npt.ArrayLike) -> FloatArray:
    """Class probabilities from ``Booster.predict(DMatrix)`` (float32 widened to float64)."""
    result: FloatArray = np.asarray(b.predict(_matrix(values), validate_features=False), np.float64)
    return result


def xgboost_margins(b: Any, values: npt.ArrayLike) -> npt.NDArray[np.float32]:
    """Per-class margins (``output_margin=True``), float32 as XGBoost computes them."""
    result: npt.NDArray[np.float32] = b.predict(
        _matrix(values), output_margin=True, validate_features=False
    )
    return result


def xgboost_inplace(b: Any, values: npt.ArrayLike) -> FloatArray:
    """Class probabilities from ``Booster.inplace_predict`` (no DMatrix)."""
    result: FloatArray = np.asarray(
        b.inplace_predict(np.asarray(values, dtype=np.float32), missing=np.nan), np.float64
    )
    return result


def model_thresholds(model_path: Path, n_features: int) -> list[npt.NDArray[np.float32]]:
    """Every split threshold of the model, per feature (sorted, unique; float32)."""
    model = json.loads(model_path.read_bytes())
    trees = model["learner"]["gradient_booster"]["model"]["trees"]
    per: list[list[float]] = [[] for _ in range(n_features)]
    for tree in trees:
        for left, feature, cond in zip(
            tree["left_children"], tree["split_indices"], tree["split_conditions"], strict=True
        ):
            if left >= 0:
                per[int(feature)].append(float(cond))
    return [np.unique(np.asarray(v, dtype=np.float32)) for v in per]
