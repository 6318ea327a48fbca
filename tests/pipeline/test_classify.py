"""Examples for the tree evaluator and the classifier's loading and scoring (SR-CLS-1, -3)."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import numpy as np
import pytest
import xgboost as xgb

from pipeline.classify.model import (
    MODEL_CLASSES,
    Classifier,
    ModelError,
    ModelHashError,
    card_path,
    file_sha256,
    model_provenance,
    unscored,
)
from pipeline.classify.trees import ModelFormatError, TreeEnsemble
from pipeline.config import default_config, overridden
from pipeline.features import FEATURE_NAMES, N_FEATURES
from pipeline.types import TrackFeatures, TrackStatus


def _toy_model(depth: int, rounds: int, classes: int = 3, seed: int = 0) -> bytes:
    rng = np.random.default_rng(seed)
    x = rng.normal(size=(600, N_FEATURES)).astype(np.float32)
    x[rng.random(x.shape) < 0.1] = np.nan
    y = rng.integers(0, classes, size=x.shape[0])  # noise: the trees grow to full depth
    params = {
        "objective": "multi:softprob",
        "num_class": classes,
        "max_depth": depth,
        "min_child_weight": 0.0,
        "nthread": 1,
        "seed": seed,
    }
    booster = xgb.train(params, xgb.DMatrix(x, label=y), rounds)
    return bytes(booster.save_raw("json"))


def _write(folder: Path, data: bytes, classes: tuple[str, ...]) -> Path:
    path = folder / "classifier.json"
    path.write_bytes(data)
    card = {
        "model_sha256": file_sha256(path),
        "class_names": list(classes),
        "feature_names": list(FEATURE_NAMES),
    }
    card_path(path).write_text(json.dumps(card))
    return path


@pytest.mark.requirement("SR-CLS-1", kind="cross-check", code=["pipeline/classify/trees.py"])
@pytest.mark.parametrize(("depth", "bitmask"), [(3, True), (6, True), (8, False)])
def test_both_paths_equal_xgboost_on_toy_models(depth: int, bitmask: bool) -> None:
    data = _toy_model(depth, 6 if depth > 6 else 12)
    ensemble = TreeEnsemble.from_json(data)
    assert ensemble.bitmask is bitmask
    booster = xgb.Booster()
    booster.load_model(bytearray(data))
    rng = np.random.default_rng(1)
    x = rng.normal(size=(700, N_FEATURES)) * 2
    x[rng.random(x.shape) < 0.2] = np.nan
    ref = booster.predict(xgb.DMatrix(x.astype(np.float32)), output_margin=True)
    assert np.array_equal(ensemble.margins(x), ref)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda m: m["learner"]["objective"].update(name="binary:logistic"), "objective"),
        (lambda m: m["learner"]["gradient_booster"].update(name="gblinear"), "booster"),
        (lambda m: m["learner"]["gradient_booster"]["model"].update(tree_info=[0]), "tree_info"),
        (lambda m: m["learner"].pop("learner_model_param"), "learner_model_param"),
    ],
)
def test_unsupported_models_are_refused(edit: object, message: str) -> None:
    model = json.loads(_toy_model(2, 2))
    edit(model)  # type: ignore[operator]
    with pytest.raises(ModelFormatError, match=message):
        TreeEnsemble(model)
    with pytest.raises(ModelFormatError, match="not JSON"):
        TreeEnsemble.from_json(b"\x00ubj")


def test_loading_verifies_hash_card_features_and_classes(tmp_path: Path) -> None:
    data = _toy_model(2, 2)
    path = _write(tmp_path, data, ("a", "b", "c"))
    clf = Classifier(path)
    assert clf.model_sha256 == file_sha256(path)
    assert clf.class_index("b") == 1
    assert clf.class_index("person") == -1
    with pytest.raises(ModelHashError, match="expected " + "1" * 64):
        Classifier(path, expected_sha256="1" * 64)
    with pytest.raises(ModelError, match="cannot read"):
        Classifier(tmp_path / "missing.json")
    card = json.loads(card_path(path).read_text())
    card_path(path).write_text(json.dumps({**card, "class_names": ["a", "b"]}))
    with pytest.raises(ModelError, match="2 classes"):
        Classifier(path)
    card_path(path).write_text(json.dumps({**card, "feature_names": ["x"] * 10}))
    with pytest.raises(ModelError, match="trained on features"):
        Classifier(path)
    card_path(path).unlink()
    with pytest.raises(ModelError, match="model card"):
        Classifier(path)
    info = model_provenance(
        overridden(default_config(), {"classify": {"model_path": str(path)}}).classify
    )
    assert info["sha256"] == file_sha256(path)
    assert "error" in info


@pytest.mark.requirement("SR-CLS-3", kind="example", code=["pipeline/classify/model.py"])
def test_a_thread_parses_a_model_once_and_still_checks_its_hash_on_every_load(
    tmp_path: Path,
) -> None:
    """Classifiers of one thread share the parsed trees of a model (keyed by the file's
    SHA-256); another thread parses its own (scratch buffers); every load re-reads and
    re-hashes the file, so a changed file is refused or, pinned to its new hash, parsed anew."""
    folder = tmp_path / "m"
    folder.mkdir()
    path = _write(folder, _toy_model(2, 2), ("a", "b", "c"))
    a, b = Classifier(path), Classifier(path)
    assert a.ensemble is b.ensemble
    other: list[Classifier] = []
    worker = threading.Thread(target=lambda: other.append(Classifier(path)))
    worker.start()
    worker.join()
    assert other[0].ensemble is not a.ensemble
    x = np.random.default_rng(2).normal(size=(5, N_FEATURES))
    assert np.array_equal(other[0].probabilities(x), a.probabilities(x))
    pinned = a.model_sha256
    changed = _toy_model(2, 2, seed=1)
    path.write_bytes(changed)
    with pytest.raises(ModelHashError):
        Classifier(path, expected_sha256=pinned)
    c = Classifier(path, expected_sha256=file_sha256(path))
    assert c.ensemble is not a.ensemble
    assert np.array_equal(c.ensemble.margins(x), TreeEnsemble.from_json(changed).margins(x))


def test_classify_scores_confirmed_and_lost_tracks_only(tmp_path: Path) -> None:
    path = _write(tmp_path, _toy_model(3, 4, classes=len(MODEL_CLASSES)), MODEL_CLASSES)
    clf = Classifier(path)
    status = [TrackStatus.TENTATIVE, TrackStatus.CONFIRMED, TrackStatus.LOST, TrackStatus.DORMANT]
    values = np.zeros((5, N_FEATURES))
    values[:, 3] = np.nan  # coasting: no density this cycle
    values[4, 0] = np.inf  # impossible value: not scored, counted
    feats = TrackFeatures(
        1.0, np.arange(5), np.array([int(s) for s in status] + [int(TrackStatus.CONFIRMED)]), values
    )
    result = clf.classify(feats)
    assert result.scored.tolist() == [False, True, True, False, False]
    assert np.isnan(result.probability[0]).all()
    assert result.confidence[0] == 0.0
    assert np.allclose(result.probability[1:3].sum(axis=1), 1.0)
    assert result.model_sha256 == clf.model_sha256
    assert clf.rows_rejected == 1
    fallback = unscored(feats, MODEL_CLASSES)
    assert (fallback.class_index == -1).all()
    assert (fallback.confidence == 0).all()


def test_packaged_model_provenance_is_verified() -> None:
    info = model_provenance(default_config().classify)
    assert info["verified"] is True
    assert info["sha256"] == info["card_sha256"]
    folder = Path(info["path"]).parent
    assert (folder / "classifier.sha256").read_text().split()[0] == info["sha256"]


_MINI_CATALOGUE = """
schema_version = 1
[families]
X = "Example family"

[[requirement]]
id = "SR-X-1"
family = "X"
status = "claimed"
claim = "Something holds."
source = "test"
evidence_kinds = ["example"]
minimum = { example = 1 }
code = ["m.py"]
"""


@pytest.mark.requirement("SR-CLS-3", kind="example", code=["pipeline/classify/model.py"])
def test_every_evidence_bundle_records_the_model_hash(pytester: pytest.Pytester) -> None:
    """Whatever the session runs, its bundle's provenance names the model and its hash."""
    pytester.makefile(".toml", catalogue=_MINI_CATALOGUE)
    pytester.makepyfile(
        test_m="import pytest\n\n@pytest.mark.requirement('SR-X-1')\ndef test_a():\n    pass\n"
    )
    out = pytester.path / "bundle"
    result = pytester.runpytest(
        "--safecase-requirements=catalogue.toml",
        "-o",
        "safecase_runtime=true",  # safecase's own suite records its model (docs/plugin.md)
        f"--safecase-out={out}",
        f"--safecase-key={pytester.path / 'key.pem'}",
        "-p",
        "no:cacheprovider",
    )
    assert result.ret == 0
    prov = json.loads((out / "evidence.json").read_text())["provenance"]
    info = prov["classifier_model"]
    assert info["sha256"] == model_provenance(default_config().classify)["sha256"]
    assert info["verified"] is True
