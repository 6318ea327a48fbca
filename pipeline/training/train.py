"""Training the classifier from simulator data, seeded and deterministic (SR-CLS-2).

What it does, in order:

1. Runs the data plan (:func:`pipeline.training.plan.data_plan`): every named scenario, the
   randomised encounter generator and the reversal drills
   (:func:`pipeline.training.data.reversal_drill`), each with its own seeds, through the
   run-time perception path (``--cache`` keeps the rows by block of runs, so a grown plan
   simulates only its new blocks), and labels the rows from the ground
   truth (:mod:`pipeline.training.data`). The held-out test plan uses seeds from
   :data:`TEST_SEED_BASE` on, never seen in training.
2. Keeps a fixed share (``--static-keep``) of the plentiful ``static`` rows of the training set
   (drawn with a generator seeded by ``classify.train_seed``) and weights every class inversely
   to its row count, so the rare near-reversal rows count as much as the common ones.
3. Trains an XGBoost ``multi:softprob`` booster over the classifier's classes
   (:data:`pipeline.classify.model.MODEL_CLASSES`; simulator classes mapped by
   :data:`pipeline.training.data.SIM_TO_MODEL_CLASS`) with ``classify.max_depth``,
   ``classify.n_estimators``, ``classify.learning_rate``, ``classify.max_bin``,
   ``seed = classify.train_seed``, the ``hist`` method and ONE thread (``nthread = 1``:
   multi-threaded histogram building may sum gradients in another order from run to run), so
   the same inputs give the same model bytes.
4. Writes ``classifier.json`` (XGBoost's JSON model), ``classifier.card.json`` (SHA-256, class
   and feature names, XGBoost version, parameters, the data plan and the rows per class, the
   held-out accuracy per class) and ``classifier.sha256`` (``sha256sum -c`` format), and the
   held-out rows (``--heldout``) for the evidence.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np

from pipeline.classify.model import MODEL_CLASSES, PACKAGED_MODEL, card_path
from pipeline.config import ClassifySection, SafecaseConfig, config_hash
from pipeline.errors import SafecaseError
from pipeline.features import FEATURE_NAMES
from pipeline.sources.sim.truth import CLASS_NAMES
from pipeline.training.data import SIM_TO_MODEL_CLASS, Rows, RunSpec, save_rows
from pipeline.training.plan import cached_rows, data_plan

__all__ = [
    "TEST_SEED_BASE",
    "TrainOptions",
    "TrainingError",
    "accuracy_by_class",
    "class_weights",
    "train",
    "train_booster",
    "write_model",
]

TEST_SEED_BASE = 100_000


class TrainingError(SafecaseError, ValueError):
    """Training options that cannot give a model (an empty data plan)."""


def thin_static(rows: Rows, keep: float, seed: int) -> Rows:
    """All non-static rows and a seeded random share ``keep`` of the static ones."""
    static = rows.label == CLASS_NAMES.index("static")
    draw = np.random.default_rng(seed).random(rows.n)
    return rows.take(~static | (draw < keep))


def class_weights(label: np.ndarray, n_classes: int) -> np.ndarray:
    """Per-row weights inversely proportional to the row's class count (mean weight 1)."""
    counts = np.bincount(label, minlength=n_classes).astype(np.float64)
    present = counts > 0
    per_class = np.zeros(n_classes)
    per_class[present] = label.shape[0] / (present.sum() * counts[present])
    weights: np.ndarray = per_class[label]
    return weights


def train_booster(rows: Rows, section: ClassifySection) -> Any:
    """The XGBoost booster for ``rows`` (deterministic: one thread, seeded)."""
    import xgboost as xgb

    n_classes = len(MODEL_CLASSES)
    label = rows.model_label
    data = xgb.DMatrix(
        rows.features.astype(np.float32),
        label=label,
        weight=class_weights(label, n_classes),
        feature_names=list(FEATURE_NAMES),
        nthread=1,
    )
    params = {
        "objective": "multi:softprob",
        "num_class": n_classes,
        "max_depth": section.max_depth,
        "eta": section.learning_rate,
        "max_bin": section.max_bin,
        "tree_method": "hist",
        "nthread": 1,
        "seed": section.train_seed,
    }
    return xgb.train(params, data, num_boost_round=section.n_estimators)


def accuracy_by_class(label: np.ndarray, predicted: np.ndarray) -> dict[str, dict[str, float]]:
    """Per classifier class: rows and recall (share of that class's rows predicted as it);
    ``label`` and ``predicted`` are ``MODEL_CLASSES`` codes."""
    out: dict[str, dict[str, float]] = {}
    for index, name in enumerate(MODEL_CLASSES):
        mine = label == index
        n = int(mine.sum())
        if n:
            out[name] = {"rows": n, "accuracy": float((predicted[mine] == index).mean())}
    return out


def _describe(rows: Rows) -> dict[str, Any]:
    by_scenario: dict[str, list[int]] = {}
    durations = sorted({r.duration_s for r in rows.runs})
    for r in rows.runs:
        by_scenario.setdefault(r.scenario, []).append(r.seed)
    return {
        "runs": len(rows.runs),
        "duration_s": durations,
        "seeds_by_scenario": {
            k: {"first": min(v), "last": max(v), "count": len(v)} for k, v in by_scenario.items()
        },
        "rows": rows.n,
        "rows_per_simulator_class": rows.counts(),
        "rows_per_class": rows.model_counts(),
        "rows_dropped": rows.dropped,
    }


def write_model(
    booster: Any,
    out_dir: Path,
    config: SafecaseConfig,
    train: Rows,
    extra: dict[str, Any],
) -> Path:
    """Write model, card and ``.sha256`` into ``out_dir``; returns the model path."""
    import xgboost as xgb

    out_dir.mkdir(parents=True, exist_ok=True)
    model = out_dir / PACKAGED_MODEL.name
    data = bytes(booster.save_raw("json"))
    model.write_bytes(data)
    sha = hashlib.sha256(data).hexdigest()
    section = config.classify
    card = {
        "model_file": model.name,
        "model_sha256": sha,
        "format": "xgboost JSON model (Booster.save_raw('json'))",
        "xgboost_version": xgb.__version__,
        "safecase_version": metadata.version("safecase"),
        "class_names": list(MODEL_CLASSES),
        "label_map": "simulator class -> classifier class: "
        + ", ".join(f"{k} -> {v}" for k, v in SIM_TO_MODEL_CLASS.items() if k != v),
        "feature_names": list(FEATURE_NAMES),
        "params": {
            "objective": "multi:softprob",
            "max_depth": section.max_depth,
            "n_estimators": section.n_estimators,
            "learning_rate": section.learning_rate,
            "max_bin": section.max_bin,
            "tree_method": "hist",
            "nthread": 1,
            "seed": section.train_seed,
            "class_weights": "inverse class frequency, mean 1",
        },
        "config_hash": config_hash(config),
        "training_data": _describe(train),
        **extra,
    }
    card_path(model).write_text(json.dumps(card, indent=1, sort_keys=True) + "\n")
    (out_dir / "classifier.sha256").write_text(f"{sha}  {model.name}\n")
    return model


@dataclass(frozen=True)
class TrainOptions:
    """The data plan and sampling of one training run (``safecase train`` options)."""

    named_seeds: int = 30
    encounter_seeds: int = 2400
    drill_seeds: int = 1800
    test_named_seeds: int = 5
    test_encounter_seeds: int = 80
    test_drill_seeds: int = 60
    duration_s: float = 20.0
    static_keep: float = 0.2
    heldout_static_keep: float = 0.1
    workers: int = 1
    cache: Path | None = None


Progress = Callable[[str, int, int], None]


def train(
    cfg: SafecaseConfig,
    options: TrainOptions,
    out_dir: Path,
    *,
    heldout: Path | None = None,
    progress: Progress | None = None,
    say: Callable[[str], None] = lambda _: None,
) -> Path:
    """Simulate the plans, train, evaluate on the held-out plan and write the model files into
    ``out_dir`` (module docstring); returns the model path. ``progress(plan, done, total)``
    reports runs ready; ``say`` receives one line per step."""
    o = options
    seed = cfg.classify.train_seed
    train_plan = data_plan(o.named_seeds, o.encounter_seeds, o.drill_seeds, o.duration_s, 0)
    test_plan = data_plan(
        o.test_named_seeds,
        o.test_encounter_seeds,
        o.test_drill_seeds,
        o.duration_s,
        TEST_SEED_BASE,
    )
    if not train_plan:
        raise TrainingError("the training plan is empty (all seed counts are 0)")
    say(f"data plan: {len(train_plan)} training and {len(test_plan)} held-out runs")

    def rows_of(plan: list[RunSpec], what: str) -> Rows:
        def done(n: int) -> None:
            if progress is not None:
                progress(what, n, len(plan))

        return cached_rows(cfg, plan, o.workers, o.cache, done)

    rows = thin_static(rows_of(train_plan, "training plan"), o.static_keep, seed)
    test = rows_of(test_plan, "held-out plan") if test_plan else None
    say(f"training on {rows.n} rows: {rows.model_counts()}")
    booster = train_booster(rows, cfg.classify)
    extra: dict[str, Any] = {"training_data_static_keep": o.static_keep}
    if test is not None and test.n:
        from pipeline.classify.trees import TreeEnsemble

        ensemble = TreeEnsemble.from_json(bytes(booster.save_raw("json")))
        predicted = ensemble.probabilities(test.features).argmax(axis=1)
        extra["heldout"] = {
            **_describe(test),
            "accuracy_by_class": accuracy_by_class(test.model_label, predicted),
        }
        for name, row in extra["heldout"]["accuracy_by_class"].items():
            say(f"  held-out {name:24s} {row['accuracy']:7.2%} of {row['rows']} rows")
        if heldout is not None:
            kept = thin_static(test, o.heldout_static_keep, seed + 1)
            save_rows(heldout, kept)
            extra["heldout"]["stored"] = {
                "path": heldout.name,
                "static_keep": o.heldout_static_keep,
                "rows": kept.n,
            }
    return write_model(booster, out_dir, cfg, rows, extra)
