"""The classifier: fast path equals XGBoost, held-out accuracy, model hash (SR-CLS-1..3).

The model under test is the configured one (``classify.model_path``, by default the packaged
``pipeline/models/classifier.json``); the held-out rows are ``tests/data/classify/heldout.npz``,
written by the same ``safecase train`` run that produced the packaged model (simulator seeds
from 100000 on, never used in training; every non-static row and 10 % of the static ones).
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from evidence.profiles import certifying, examples
from evidence.record import Recorder, current
from pipeline.classify.model import Classifier, ModelHashError, card_path, file_sha256
from pipeline.config import SafecaseConfig, overridden
from pipeline.features import N_FEATURES, feature_index
from pipeline.predict import near_reversal_flags, track_modes
from pipeline.training.data import Rows, load_rows
from pipeline.types import Classification, FloatArray, TrackFeatures
from properties.heldout_roles import row_roles
from properties.heldout_tables import accuracy_by_role, accuracy_in_bands, errors_by_role
from properties.oracles.classify import (
    booster,
    model_thresholds,
    xgboost_inplace,
    xgboost_margins,
    xgboost_probabilities,
)
from safety.geometry.envelopes import EnvelopeBuilder

CODE = ["pipeline/classify/model.py", "pipeline/classify/trees.py"]
HELDOUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "classify" / "heldout.npz"
# Published per-class accuracy of the source material (the system we implement), stated "for
# a forklift at typical detection ranges (2 to 8 m)": SR-CLS-2 is graded on that cut.
PUBLISHED = {
    "forklift_moving": 0.943,
    "forklift_stationary": 0.917,
    "forklift_near_reversal": 0.881,
}
SOURCE_CUT_M = (2.0, 8.0)
# Range bands reported beside the source's cut [m, from the robot; each [lo, hi)].
RANGE_BANDS_M = [(0.0, 2.0), SOURCE_CUT_M, (8.0, 20.0), (20.0, math.inf), (0.0, math.inf)]


@pytest.fixture(scope="module")
def classifier(safecase_config: SafecaseConfig) -> Classifier:
    clf = Classifier.from_config(safecase_config.classify)
    current().provenance("classifier.model_sha256", clf.model_sha256)
    return clf


@pytest.fixture(scope="module")
def oracle(classifier: Classifier) -> object:
    return booster(classifier.model_path)


@pytest.fixture(scope="module")
def thresholds(classifier: Classifier) -> list[np.ndarray]:
    return model_thresholds(classifier.model_path, N_FEATURES)


@pytest.fixture(scope="module")
def heldout() -> Rows:
    if not HELDOUT.exists():
        pytest.fail(f"held-out rows {HELDOUT} missing: run `safecase train --heldout {HELDOUT}`")
    return load_rows(HELDOUT)


def feature_matrix(
    rng: np.random.Generator, thresholds: list[np.ndarray], n: int, nan_share: float
) -> FloatArray:
    """Rows that hit the model's decisions hard: split thresholds exactly and one float32 ulp
    either side, values between and beyond them, extreme finite float32 values, NaN."""
    out = np.empty((n, N_FEATURES))
    f32 = np.float32
    for f, thr in enumerate(thresholds):
        kind = rng.integers(0, 5, size=n)
        picks = thr[rng.integers(0, max(thr.shape[0], 1), size=n)] if thr.size else np.zeros(n, f32)
        exact = picks.astype(f32)
        up = np.nextafter(exact, f32(np.inf))
        down = np.nextafter(exact, f32(-np.inf))
        spread = rng.normal(size=n) * (np.abs(exact.astype(np.float64)) + 1.0) * 2.0
        extreme = rng.choice([-3e38, -1e10, -1e-30, -0.0, 0.0, 1e-30, 1e10, 3e38], size=n)
        out[:, f] = np.choose(kind, [exact, up, down, exact + spread, extreme])
    out[rng.random(out.shape) < nan_share] = np.nan
    return out


def _check_equal(classifier: Classifier, oracle: object, x: FloatArray) -> tuple[float, int]:
    """Margins bit for bit, probabilities within 1e-6, argmax equal; returns (max diff, rows)."""
    ours_margin = classifier.ensemble.margins(x)
    ref_margin = xgboost_margins(oracle, x)
    assert np.array_equal(ours_margin, ref_margin), "margins differ from xgboost's"
    ours = classifier.probabilities(x)
    ref = xgboost_probabilities(oracle, x)
    diff = float(np.abs(ours - ref).max(initial=0.0))
    assert diff <= 1e-6, f"probabilities differ from xgboost's by {diff}"
    assert np.array_equal(ours.argmax(axis=1), ref.argmax(axis=1)), "argmax differs"
    return diff, x.shape[0]


@pytest.mark.requirement("SR-CLS-1", kind="property", code=CODE)
@settings(max_examples=examples(60), deadline=None)
@given(
    n=st.integers(1, 40),
    nan_share=st.sampled_from([0.0, 0.05, 0.3, 1.0]),
    seed=st.integers(0, 2**32 - 1),
)
def test_fast_path_equals_xgboost_on_random_vectors(
    classifier: Classifier,
    oracle: object,
    thresholds: list[np.ndarray],
    n: int,
    nan_share: float,
    seed: int,
) -> None:
    x = feature_matrix(np.random.default_rng(seed), thresholds, n, nan_share)
    _diff, rows = _check_equal(classifier, oracle, x)
    rec = current()
    rec.count("rows compared", "random rows", rows)
    rec.count("rows compared", "rows with a missing value", int(np.isnan(x).any(axis=1).sum()))


@pytest.mark.requirement("SR-CLS-1", kind="cross-check", code=CODE)
def test_fast_path_equals_xgboost_on_the_heldout_set(
    classifier: Classifier, oracle: object, heldout: Rows, evidence: Recorder
) -> None:
    diff, rows = _check_equal(classifier, oracle, heldout.features)
    # XGBoost's other public path on every 10th row (the same trees; it costs as much again).
    some = heldout.features[::10]
    assert np.abs(classifier.probabilities(some) - xgboost_inplace(oracle, some)).max() <= 1e-6
    evidence.counts(
        "held-out cross-check",
        {
            "rows": rows,
            "rows with a missing value": int(np.isnan(heldout.features).any(axis=1).sum()),
            "largest |p - p_xgboost|": diff,
        },
    )
    evidence.note(
        f"path: {'leaf bitmasks' if classifier.ensemble.bitmask else 'level walk'}; "
        f"{classifier.ensemble.n_trees} trees, at most {classifier.ensemble.max_leaves} leaves"
    )


def _safety_margins(
    classification: Classification, rows: Rows, config: SafecaseConfig
) -> tuple[np.ndarray, float]:
    """Margin each row would get at run time, and the near-reversal tier's margin."""
    values = TrackFeatures(0.0, np.arange(rows.n), np.zeros(rows.n, np.int64), rows.features)
    flagged = near_reversal_flags(values, config.predict)
    near, _, _, unknown = track_modes(
        classification, flagged, config.classify.medium_confidence_min
    )
    builder = EnvelopeBuilder.from_config(config)
    confidence = np.where(unknown, 0.0, classification.confidence)
    margin, _ = builder.margins(confidence, near)
    top = float(builder.params.margins_m[2])
    return margin, top


@pytest.mark.requirement("SR-CLS-6", kind="measurement", code=[*CODE, "pipeline/features.py"])
def test_heldout_accuracy_against_the_published_figures(
    classifier: Classifier, heldout: Rows, safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    names = classifier.class_names
    p = classifier.probabilities(heldout.features)
    predicted = p.argmax(axis=1)
    label = heldout.model_label
    k = len(names)
    confusion = np.zeros((k, k), dtype=np.int64)
    np.add.at(confusion, (label, predicted), 1)
    rows, accuracy = [], {}
    for i, name in enumerate(names):
        n = int(confusion[i].sum())
        if not n:
            continue
        acc = confusion[i, i] / n
        accuracy[name] = acc
        target = PUBLISHED.get(name)
        rows.append(
            [
                name,
                n,
                f"{acc:.1%}",
                "-" if target is None else f"{target:.1%}",
                "-" if target is None else ("met" if acc >= target else "MISSED"),
            ]
        )
    evidence.table(
        "held-out accuracy per class (recall) against the published figures",
        ["class", "rows", "accuracy", "published", "target"],
        rows,
        caption=f"{heldout.n} held-out rows from {len(heldout.runs)} simulator runs; static "
        "rows thinned to 10 % when stored",
    )
    evidence.plot("confusion matrix", _confusion_figure(confusion, names), caption="rows: truth")
    published = {name: names.index(name) for name in PUBLISHED}
    roles = row_roles(heldout, safecase_config)
    # How much of the object the cluster shows: a forklift is 2.3-3.1 m long, so a box
    # shorter than 0.5 m is a sliver (a fork tip, a mast seen past an occluder).
    length = heldout.features[:, feature_index("bbox_length_m")]
    shown = [(0.0, 0.5), (0.5, 0.8), (0.8, math.inf)]
    evidence.table(
        "held-out accuracy by the length of the cluster's box",
        ["class", *[f"{lo:g}-{hi:g} m" for lo, hi in shown]],
        accuracy_in_bands(label, predicted, published, length, shown),
        caption="partial views (short boxes) carry little of the object's shape",
    )
    evidence.table(
        "held-out accuracy by scenario and object",
        ["scenario", "object", *PUBLISHED],
        accuracy_by_role(roles, label, predicted, published),
        caption="the drill's cross_forklift is seen through the 3.5 m gap between the rack rows "
        "24-27 m ahead: a truck longer than the gap fills it moving or not",
    )

    # Safety-relevant errors: a near-reversal forklift given a smaller margin than the
    # near-reversal tier's (the classifier called it something else with enough confidence).
    conf = p[np.arange(p.shape[0]), predicted]
    classification = Classification(
        0.0, np.arange(heldout.n), predicted, p, conf, names, classifier.model_sha256
    )
    margin, top = _safety_margins(classification, heldout, safecase_config)
    near_code = names.index("forklift_near_reversal")
    truly_near = label == near_code
    smaller = truly_near & (margin < top)
    by_class = {names[c]: int(np.count_nonzero(smaller & (predicted == c))) for c in range(k)}
    evidence.table(
        "safety-relevant errors: near-reversal forklifts given a smaller margin",
        ["predicted as", "rows", "share of near-reversal rows"],
        [
            [name, n, f"{n / max(int(truly_near.sum()), 1):.2%}"]
            for name, n in sorted(by_class.items(), key=lambda kv: -kv[1])
            if n
        ]
        + [["total", int(smaller.sum()), f"{smaller.sum() / max(int(truly_near.sum()), 1):.2%}"]],
        caption=f"margin below the near-reversal tier's {top} m; rows misclassified with low "
        "confidence or as a forklift whose kinematics say near reversal keep the largest margin",
    )
    evidence.table(
        "safety-relevant errors by scenario and object",
        ["scenario", "object", "near-reversal rows given a smaller margin", "predicted as"],
        errors_by_role(roles, smaller, truly_near, predicted, names),
        caption="a truck whose view shows no motion is called what such views mostly are",
    )
    person = names.index("person")
    evidence.counts(
        "safety-relevant errors",
        {
            "near-reversal rows": int(truly_near.sum()),
            "near-reversal rows given a smaller margin": int(smaller.sum()),
            "person rows": int((label == person).sum()),
            "person rows not called person": int(((label == person) & (predicted != person)).sum()),
        },
    )
    # The stored rows and the model belong together: the card's held-out figures (measured on
    # every held-out row at training time) reproduce for every class stored in full.
    card = classifier.card.get("heldout", {}).get("accuracy_by_class", {})
    for name, acc in accuracy.items():
        if name != "static" and name in card:
            assert acc == pytest.approx(card[name]["accuracy"], abs=1e-12), name


def _in_cut(rows: Rows) -> np.ndarray:
    """Rows inside the source's 2-8 m cut (``[2, 8)`` m from the robot)."""
    lo, hi = SOURCE_CUT_M
    return (rows.range_m >= lo) & (rows.range_m < hi)


def _band_name(lo: float, hi: float) -> str:
    if lo == 0.0 and hi == math.inf:
        return "all ranges"
    return f"beyond {lo:g} m" if hi == math.inf else f"{lo:g}-{hi:g} m"


SR_CLS_2_CODE = [*CODE, "pipeline/features.py", "pipeline/shape/ends.py"]


@pytest.mark.requirement("SR-CLS-2", kind="measurement", code=SR_CLS_2_CODE)
def test_heldout_accuracy_on_the_source_cut(
    classifier: Classifier, heldout: Rows, evidence: Recorder
) -> None:
    """Forklift recall on the held-out rows at 2-8 m (the source's cut) against the published
    figures, every other range band and all ranges beside it (the assertion is the xfail below:
    this test reports)."""
    names = classifier.class_names
    predicted = classifier.probabilities(heldout.features).argmax(axis=1)
    label = heldout.model_label
    published = {name: names.index(name) for name in PUBLISHED}
    table = accuracy_in_bands(label, predicted, published, heldout.range_m, RANGE_BANDS_M)
    cut = _in_cut(heldout)
    verdict = {}
    for row, (name, code) in zip(table, published.items(), strict=True):
        mine = cut & (label == code)
        reached = float((predicted[mine] == code).mean()) if mine.any() else 0.0
        verdict[name] = reached
        row.insert(1, f"{PUBLISHED[name]:.1%}")
        row.append("met" if reached >= PUBLISHED[name] else "MISSED")
    evidence.table(
        "SR-CLS-2: held-out forklift recall by range band (graded on the source's 2-8 m cut)",
        [
            "class",
            "published (2-8 m)",
            *[_band_name(lo, hi) for lo, hi in RANGE_BANDS_M],
            "target (2-8 m)",
        ],
        table,
        caption="range from the robot, bands [lo, hi); the source states its figures for a "
        "forklift at 2 to 8 m, so the 2-8 m column is graded; the others are reported",
    )
    evidence.counts(
        "SR-CLS-2 on the 2-8 m cut",
        {f"{name} recall": round(value, 4) for name, value in verdict.items()}
        | {"rows in the cut": int(cut.sum())},
    )
    assert int(cut.sum()) > 0, "no held-out row lies in the 2-8 m cut"


@pytest.mark.requirement("SR-CLS-2", kind="measurement", code=SR_CLS_2_CODE)
@pytest.mark.xfail(
    reason="the published per-class accuracy is not reached on the 2-8 m cut "
    "(docs/findings/classification.md); strict: reaching it fails this marker, and SR-CLS-2 "
    "can then be claimed",
    strict=True,
)
def test_heldout_accuracy_reaches_the_published_figures(
    classifier: Classifier, heldout: Rows
) -> None:
    predicted = classifier.probabilities(heldout.features).argmax(axis=1)
    names = classifier.class_names
    cut = _in_cut(heldout)
    reached = {}
    for name in PUBLISHED:
        mine = cut & (heldout.model_label == names.index(name))
        reached[name] = float((predicted[mine] == names.index(name)).mean())
    missed = {k: f"{v:.1%} < {PUBLISHED[k]:.1%}" for k, v in reached.items() if v < PUBLISHED[k]}
    assert not missed, f"below the published accuracy at 2-8 m: {missed}"


def _confusion_figure(confusion: np.ndarray, names: tuple[str, ...]) -> object:
    import matplotlib.pyplot as plt

    share = confusion / np.maximum(confusion.sum(axis=1, keepdims=True), 1)
    fig, ax = plt.subplots(figsize=(8.5, 7.5))
    ax.imshow(share, cmap="Blues", vmin=0.0, vmax=1.0)
    ax.set_xticks(range(len(names)), names, rotation=60, ha="right", fontsize=8)
    ax.set_yticks(range(len(names)), names, fontsize=8)
    ax.set_xlabel("predicted")
    ax.set_ylabel("true")
    for i in range(len(names)):
        for j in range(len(names)):
            if confusion[i, j]:
                ax.text(
                    j,
                    i,
                    f"{share[i, j]:.2f}\n{confusion[i, j]}",
                    ha="center",
                    va="center",
                    fontsize=6,
                    color="white" if share[i, j] > 0.5 else "black",
                )
    ax.set_title("held-out confusion (share of each true class; count)")
    fig.tight_layout()
    return fig


@pytest.mark.requirement("SR-CLS-3", kind="example", code=["pipeline/classify/model.py"])
def test_model_hash_is_verified_on_load_and_recorded(
    classifier: Classifier, safecase_config: SafecaseConfig, tmp_path: Path, evidence: Recorder
) -> None:
    path = classifier.model_path
    assert classifier.model_sha256 == file_sha256(path) == classifier.card["model_sha256"]
    evidence.provenance("classifier.model_sha256", classifier.model_sha256)
    # A copy with one byte changed is refused with the typed error, naming both hashes.
    copy = tmp_path / path.name
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    copy.write_bytes(bytes(data))
    shutil.copy(card_path(path), card_path(copy))
    with pytest.raises(ModelHashError, match=classifier.model_sha256):
        Classifier(copy)
    # A pinned hash in the configuration must match too.
    pinned = overridden(
        safecase_config, {"classify": {"model_path": str(path), "model_sha256": "0" * 64}}
    )
    with pytest.raises(ModelHashError, match="0" * 64):
        Classifier.from_config(pinned.classify)
    evidence.note(
        f"model {path.name} sha256 {classifier.model_sha256}; the evidence bundle's provenance "
        "records it under classifier_model (every session) and classifier.model_sha256"
    )


# SR-CLS-4: the runtime path at least this many times faster than xgboost's inplace_predict at
# the p50 and at the p99 of the same interleaved run (a ratio: load on the shared machine hits
# both alike, where an absolute time would measure the machine).
TARGET_SPEEDUP = 3.0


@pytest.fixture(scope="module")
def twenty_tracks(heldout: Rows) -> FloatArray:
    """20 held-out rows, one per class where possible (a busy cycle's worth of tracks)."""
    rng = np.random.default_rng(20)
    label = heldout.model_label
    picks = [int(rng.choice(np.flatnonzero(label == c))) for c in np.unique(label)]
    rest = rng.choice(heldout.n, size=20 - len(picks), replace=False)
    return np.ascontiguousarray(heldout.features[np.concatenate([picks, rest])[:20]])


@pytest.mark.requirement("SR-CLS-4", kind="measurement", code=CODE)
@pytest.mark.parametrize("path", ["ours", "xgboost inplace_predict", "xgboost predict(DMatrix)"])
def test_inference_speed_20_tracks(
    path: str, classifier: Classifier, oracle: object, twenty_tracks: FloatArray, benchmark: object
) -> None:
    """pytest-benchmark of each path on the same 20 rows (same benchmark group)."""
    fn = {
        "ours": lambda: classifier.probabilities(twenty_tracks),
        "xgboost inplace_predict": lambda: xgboost_inplace(oracle, twenty_tracks),
        "xgboost predict(DMatrix)": lambda: xgboost_probabilities(oracle, twenty_tracks),
    }[path]
    benchmark.group = "classifier: 20 tracks"  # type: ignore[attr-defined]
    result = benchmark(fn)  # type: ignore[operator]
    assert np.abs(result - classifier.probabilities(twenty_tracks)).max() <= 1e-6


@pytest.mark.requirement("SR-CLS-4", kind="measurement", code=CODE)
@pytest.mark.requirement("SR-CLS-7", kind="measurement", code=CODE)
def test_inference_speed_ratio(
    classifier: Classifier, oracle: object, twenty_tracks: FloatArray, evidence: Recorder
) -> None:
    """Interleaved timing of the three paths in one loop (load hits them alike)."""
    from evidence.timing import compare

    timings = compare(
        {
            "ours (leaf bitmasks, numpy)": lambda: classifier.probabilities(twenty_tracks),
            "xgboost inplace_predict": lambda: xgboost_inplace(oracle, twenty_tracks),
            "xgboost predict(DMatrix)": lambda: xgboost_probabilities(oracle, twenty_tracks),
        },
        reference="xgboost inplace_predict",
        rounds=2000 if certifying() else 300,
        title="classifier, 20 tracks",
    )
    ours = timings["ours (leaf bitmasks, numpy)"]
    ref = timings["xgboost inplace_predict"]
    p50, p99 = ref.p50_s / ours.p50_s, ref.p99_s / ours.p99_s
    evidence.counts(
        "classifier, 20 tracks",
        {
            "ours p50 ms": round(ours.p50_s * 1e3, 4),
            "ours p99 ms": round(ours.p99_s * 1e3, 4),
            "speed-up over inplace_predict at p50": round(p50, 2),
            "speed-up over inplace_predict at p99": round(p99, 2),
            "target speed-up (p50 and p99)": TARGET_SPEEDUP,
            "target met": int(min(p50, p99) >= TARGET_SPEEDUP),
            "trees": classifier.ensemble.n_trees,
        },
    )
    evidence.note(
        f"{classifier.ensemble.n_trees} trees ({len(classifier.class_names)} classes x "
        f"{classifier.ensemble.n_trees // len(classifier.class_names)} rounds); speed-up over "
        f"inplace_predict {p50:.2f}x at p50, {p99:.2f}x at p99 (target {TARGET_SPEEDUP:g}x at "
        "both; reported, not asserted: SR-CLS-7); measured on a shared 2-core machine"
    )
