"""``safecase train``: the classifier from simulator data, seeded and deterministic (SR-CLS-2).

What it does, in order:

1. Runs the data plan (:func:`pipeline.classify_plan.data_plan`): every named scenario, the
   randomised encounter generator and the reversal drills
   (:func:`pipeline.classify_data.reversal_drill`), each with its own seeds, through the
   run-time perception path (``--cache`` keeps the rows by block of runs, so a grown plan
   simulates only its new blocks), and labels the rows from the ground
   truth (:mod:`pipeline.classify_data`). The held-out test plan uses seeds from
   :data:`TEST_SEED_BASE` on, never seen in training.
2. Keeps a fixed share (``--static-keep``) of the plentiful ``static`` rows of the training set
   (drawn with a generator seeded by ``classify.train_seed``) and weights every class inversely
   to its row count, so the rare near-reversal rows count as much as the common ones.
3. Trains an XGBoost ``multi:softprob`` booster over the classifier's classes
   (:data:`pipeline.classify.MODEL_CLASSES`; simulator classes mapped by
   :data:`pipeline.classify_data.SIM_TO_MODEL_CLASS`) with ``classify.max_depth``,
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
from importlib import metadata
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from pipeline.classify import MODEL_CLASSES, PACKAGED_MODEL, card_path
from pipeline.classify_data import SIM_TO_MODEL_CLASS, Rows, RunSpec, save_rows
from pipeline.classify_plan import cached_rows, data_plan
from pipeline.config import ClassifySection, SafecaseConfig, config_hash, load_config
from pipeline.errors import ConfigError
from pipeline.features import FEATURE_NAMES
from pipeline.sim.truth import CLASS_NAMES

__all__ = [
    "TEST_SEED_BASE",
    "accuracy_by_class",
    "class_weights",
    "train_booster",
    "train_command",
    "write_model",
]

TEST_SEED_BASE = 100_000


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


def train_command(
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for the model files.")] = (
        PACKAGED_MODEL.parent
    ),
    named_seeds: Annotated[int, typer.Option(min=0, help="Seeds per named scenario.")] = 30,
    encounter_seeds: Annotated[int, typer.Option(min=0, help="random_encounter seeds.")] = 2400,
    drill_seeds: Annotated[int, typer.Option(min=0, help="Reversal drill seeds.")] = 1800,
    test_named_seeds: Annotated[int, typer.Option(min=0, help="Held-out seeds per named.")] = 5,
    test_encounter_seeds: Annotated[int, typer.Option(min=0)] = 80,
    test_drill_seeds: Annotated[int, typer.Option(min=0)] = 60,
    duration: Annotated[float, typer.Option(min=0.5, help="Run length in seconds.")] = 20.0,
    static_keep: Annotated[float, typer.Option(min=0.0, max=1.0)] = 0.2,
    heldout: Annotated[
        Path | None, typer.Option(help="Write the held-out rows here (.npz).")
    ] = None,
    heldout_static_keep: Annotated[float, typer.Option(min=0.0, max=1.0)] = 0.1,
    workers: Annotated[int, typer.Option(min=1, help="Simulation processes.")] = 1,
    cache: Annotated[
        Path | None, typer.Option(help="Folder to keep simulated rows in between runs.")
    ] = None,
    config: Annotated[
        Path | None, typer.Option("--config", "-c", help="TOML configuration file.")
    ] = None,
) -> None:
    """Train the track classifier on simulator data (deterministic for given options)."""
    try:
        cfg = load_config(config)
    except ConfigError as exc:
        for line in exc.lines:
            typer.echo(f"config error: {line}", err=True)
        raise typer.Exit(2) from None
    if named_seeds + encounter_seeds + drill_seeds == 0:
        typer.echo("error: the training plan is empty (all seed counts are 0)", err=True)
        raise typer.Exit(2)
    seed = cfg.classify.train_seed
    train_plan = data_plan(named_seeds, encounter_seeds, drill_seeds, duration, 0)
    test_plan = data_plan(
        test_named_seeds, test_encounter_seeds, test_drill_seeds, duration, TEST_SEED_BASE
    )
    typer.echo(f"data plan: {len(train_plan)} training and {len(test_plan)} held-out runs")
    with Progress(
        TextColumn("[bold]simulating[/] {task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("runs"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        transient=True,
    ) as bar:

        def rows_of(plan: list[RunSpec], what: str) -> Rows:
            task = bar.add_task(what, total=len(plan))
            return cached_rows(
                cfg, plan, workers, cache, lambda done: bar.update(task, completed=done)
            )

        train = thin_static(rows_of(train_plan, "training plan"), static_keep, seed)
        test = rows_of(test_plan, "held-out plan") if test_plan else None
    typer.echo(f"training on {train.n} rows: {train.model_counts()}")
    booster = train_booster(train, cfg.classify)
    extra: dict[str, Any] = {"training_data_static_keep": static_keep}
    if test is not None and test.n:
        from pipeline.trees import TreeEnsemble

        ensemble = TreeEnsemble.from_json(bytes(booster.save_raw("json")))
        predicted = ensemble.probabilities(test.features).argmax(axis=1)
        extra["heldout"] = {
            **_describe(test),
            "accuracy_by_class": accuracy_by_class(test.model_label, predicted),
        }
        for name, row in extra["heldout"]["accuracy_by_class"].items():
            typer.echo(f"  held-out {name:24s} {row['accuracy']:7.2%} of {row['rows']} rows")
        if heldout is not None:
            kept = thin_static(test, heldout_static_keep, seed + 1)
            save_rows(heldout, kept)
            extra["heldout"]["stored"] = {
                "path": heldout.name,
                "static_keep": heldout_static_keep,
                "rows": kept.n,
            }
    model = write_model(booster, out, cfg, train, extra)
    typer.echo(f"wrote {model} sha256 {hashlib.sha256(model.read_bytes()).hexdigest()}")
