"""The safety case traces, and its argument follows this run's evidence (SR-EVD-4).

Checked on the project's own hazard log and catalogue: every claimed (or unmet) requirement
mitigates a hazard, every hazard is mitigated, every assumption names what exists. The
argument built from a bundle turns a hazard and the top goal red when one of its requirements
fails, and its gsn2x export reads back to the same structure.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from evidence.argument import TOP, build_argument, read_gsn2x, to_gsn2x
from evidence.catalogue import load_catalogue
from evidence.gsn_svg import render_svg
from evidence.model import Bundle, EvidenceItem, compute_verdicts
from evidence.record import Recorder
from evidence.safety_case import load_safety_case, trace_problems
from pipeline.config import SafecaseConfig

CODE = ["safety/hazards.toml", "evidence/safety_case.py", "evidence/argument.py"]
PREFIX = {"goal": "G", "strategy": "S", "solution": "Sn", "context": "C", "assumption": "A"}


def _bundle(config: SafecaseConfig, failing: str | None) -> Bundle:
    """Every claimed requirement evidenced by one passing item of each kind it needs, and
    ``failing`` (if given) with one failing item."""
    catalogue = load_catalogue()
    items = []
    for r in catalogue.requirements:
        for kind, n in r.minimum:
            for k in range(n):
                items.append(
                    EvidenceItem(f"t::{r.id}-{kind}-{k}", "t.py", [r.id], kind, "passed", 0.0)
                )
    if failing is not None:
        items.append(EvidenceItem("t::broken", "t.py", [failing], "example", "failed", 0.0))
    return Bundle(
        created_utc="2026-01-01T00:00:00+00:00",
        profile="ci",
        provenance={"config": config.model_dump(mode="json"), "config_hash": "0" * 64},
        environment={},
        catalogue_path=catalogue.path,
        families=dict(catalogue.families),
        requirements=compute_verdicts(catalogue, items),
        tests=items,
        session_exit_status=0,
        safety_case=load_safety_case(),
    )


@pytest.mark.requirement("SR-EVD-4", kind="example", code=CODE)
def test_the_hazard_log_traces_both_ways(
    safecase_config: SafecaseConfig, evidence: Recorder
) -> None:
    case = load_safety_case()
    catalogue = load_catalogue()
    assert trace_problems(case, catalogue, safecase_config) == []
    claimed = [r.id for r in catalogue.requirements if r.status != "planned"]
    evidence.counts(
        "safety case",
        {
            "hazards": len(case.hazards),
            "assumptions": len(case.assumptions),
            "requirements traced": len(claimed),
            "assumptions not monitored": sum(1 for a in case.assumptions if not a.watched),
        },
    )
    # The check finds each kind of break.
    h1 = case.hazards[0]
    broken = dataclasses.replace(
        case,
        hazards=(dataclasses.replace(h1, mitigated_by=()), *case.hazards[1:]),
        assumptions=(
            dataclasses.replace(case.assumptions[0], monitor="nope", keys=("stopping.nope",)),
            *case.assumptions[1:],
        ),
    )
    problems = trace_problems(broken, catalogue, safecase_config)
    assert "H-1: mitigated by no requirement" in problems
    assert "A-1: unknown configuration key stopping.nope" in problems
    assert any(p.startswith("A-1: unknown monitor 'nope'") for p in problems)
    only_in_h1 = set(h1.mitigated_by) - {r for h in case.hazards[1:] for r in h.mitigated_by}
    assert {
        f"{r} (claimed): mitigates no hazard" for r in only_in_h1 if catalogue.get(r).claimed
    } <= set(problems)


@pytest.mark.requirement("SR-EVD-4", kind="example", code=[*CODE, "evidence/gsn_svg.py"])
def test_a_failing_item_turns_its_branch_red_and_the_export_reads_back(
    safecase_config: SafecaseConfig, tmp_path: Path
) -> None:
    good = build_argument(
        _bundle(safecase_config, None), load_safety_case(), safecase_config.model_dump(mode="json")
    )
    bad = build_argument(
        _bundle(safecase_config, "SR-DRV-2"),
        load_safety_case(),
        safecase_config.model_dump(mode="json"),
    )
    assert good.nodes["G-H-5"].status == "ok"
    assert bad.nodes["G-SR-DRV-2"].status == "bad"
    assert bad.nodes["Sn-SR-DRV-2"].status == "bad"
    assert bad.nodes["G-H-5"].status == "bad"  # corrupted frames: mitigated by SR-DRV-2
    assert bad.nodes[TOP].status == "bad"
    assert bad.nodes["G-H-1"].status == good.nodes["G-H-1"].status  # other branches unchanged
    # gsn2x: every ID carries its element's prefix; every link points at a node of the right kind.
    doc = read_gsn2x(to_gsn2x(bad))
    assert set(doc) == set(bad.nodes)
    for node_id, entry in doc.items():
        node = bad.nodes[node_id]
        assert node_id.split("-")[0] == PREFIX[node.kind]
        assert entry["text"] == node.text
        assert entry["classes"] == [node.status]
        for target in entry.get("supportedBy", []):
            assert bad.nodes[target].kind in ("goal", "strategy", "solution")
        for target in entry.get("inContextOf", []):
            assert bad.nodes[target].kind in ("context", "assumption")
    # The SVG is well-formed XML naming every node it draws.
    svg = render_svg(bad, "G-H-5", depth=2, title="H-5")
    root = ET.fromstring(svg)
    texts = " ".join(t.text or "" for t in root.iter("{http://www.w3.org/2000/svg}text"))
    for node_id in ("G-H-5", "C-H-5", "G-SR-DRV-2", "Sn-SR-DRV-2"):
        assert node_id in texts
