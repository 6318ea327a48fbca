"""`safecase train` on a tiny plan: deterministic, documented, loadable (SR-CLS-3)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from evidence.cli.main import app
from pipeline.classify.model import Classifier, card_path, file_sha256
from pipeline.training.data import load_rows
from pipeline.training.plan import data_plan
from pipeline.training.train import class_weights

TINY = [
    "--named-seeds",
    "0",
    "--encounter-seeds",
    "0",
    "--drill-seeds",
    "1",
    "--test-named-seeds",
    "0",
    "--test-encounter-seeds",
    "0",
    "--test-drill-seeds",
    "1",
    "--duration",
    "3",
]


def _train(folder: Path, config: Path, *extra: str) -> Path:
    result = CliRunner().invoke(
        app, ["train", "--out", str(folder), "--config", str(config), *TINY, *extra]
    )
    assert result.exit_code == 0, result.output
    return folder / "classifier.json"


@pytest.mark.requirement("SR-CLS-3", kind="example", code=["pipeline/training/train.py"])
def test_training_is_deterministic_and_writes_a_verified_model(tmp_path: Path) -> None:
    config = tmp_path / "tiny.toml"
    config.write_text("[classify]\nn_estimators = 3\n")
    first = _train(tmp_path / "a", config, "--heldout", str(tmp_path / "a" / "heldout.npz"))
    second = _train(tmp_path / "b", config, "--cache", str(tmp_path / "cache"))
    assert first.read_bytes() == second.read_bytes()
    card = json.loads(card_path(first).read_text())
    assert card["model_sha256"] == file_sha256(first)
    assert card["params"]["nthread"] == 1
    assert card["params"]["n_estimators"] == 3
    assert card["training_data"]["seeds_by_scenario"] == {
        "reversal_drill": {"first": 0, "last": 0, "count": 1}
    }
    assert sum(card["training_data"]["rows_per_class"].values()) > 0
    assert card["xgboost_version"]
    assert (
        first.parent / "classifier.sha256"
    ).read_text() == f"{card['model_sha256']}  classifier.json\n"
    clf = Classifier(first)
    assert clf.ensemble.n_trees == 3 * len(clf.class_names)
    rows = load_rows(tmp_path / "a" / "heldout.npz")
    assert rows.n > 0
    assert rows.runs[0].seed == 100_000
    # The cached rows reproduce the model too.
    third = _train(tmp_path / "c", config, "--cache", str(tmp_path / "cache"))
    assert third.read_bytes() == first.read_bytes()


def test_bad_options_exit_2(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[classify]\nn_estimators = 0\n")
    result = CliRunner().invoke(app, ["train", "--out", str(tmp_path), "--config", str(bad)])
    assert result.exit_code == 2
    assert "classify.n_estimators" in result.output
    empty = ["--named-seeds", "0", "--encounter-seeds", "0", "--drill-seeds", "0"]
    result = CliRunner().invoke(app, ["train", "--out", str(tmp_path), *empty])
    assert result.exit_code == 2
    assert "empty" in result.output


def test_plan_and_weights() -> None:
    plan = data_plan(1, 2, 1, 5.0, 10)
    assert [(r.scenario, r.seed) for r in plan][-3:] == [
        ("random_encounter", 10),
        ("random_encounter", 11),
        ("reversal_drill", 10),
    ]
    w = class_weights(np.array([0, 0, 0, 2]), 3)
    assert w.mean() == pytest.approx(1.0)
    assert w[3] == pytest.approx(3 * w[0])
