"""The safety case as the report shows it: argument views, hazard log, assumptions, the page an
assessor prints (SR-EVD-2).

:func:`case_view` turns a bundle's hazard log and assumptions into what the report renders: the
argument's top view and one view per hazard (SVG, from :mod:`evidence.gsn_svg`), the hazard log
with each hazard's status and requirements, the assumptions with the configured values and how
each is watched, and the argument in gsn2x YAML. :func:`expected_refutations` lists the SMT
obligations that are meant to be refuted (a weakened copy of a model the harness must catch,
the source material's own configuration), so the report shows them as what they are, apart
from any requirement's verdict. :func:`render_summary` is the one-page summary.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import jinja2

from evidence.argument import TOP, build_argument, to_gsn2x
from evidence.gsn_svg import render_svg
from evidence.model import Bundle

__all__ = ["CaseView", "case_view", "expected_refutations", "render_summary"]


@dataclass(frozen=True)
class CaseView:
    """What the report shows of the safety case."""

    top_svg: str
    status: str
    hazards: list[dict[str, Any]]
    assumptions: list[dict[str, Any]]
    gsn_yaml: str


def case_view(bundle: Bundle) -> CaseView | None:
    """The safety case of ``bundle`` as the report shows it (None without a hazard log)."""
    case = bundle.safety_case
    if case is None:
        return None
    config = bundle.provenance.get("config", {})
    argument = build_argument(bundle, case, config)
    results = {r.id: r for r in bundle.requirements}
    hazards = []
    for h in case.hazards:
        goal = argument.nodes[f"G-{h.id}"]
        hazards.append(
            {
                "id": h.id,
                "title": h.title,
                "cause": h.cause,
                "situation": h.situation,
                "severity": h.severity,
                "status": goal.status,
                "requirements": [
                    (req_id, results[req_id].verdict)
                    for req_id in h.mitigated_by
                    if req_id in results
                ],
                "svg": render_svg(argument, goal.id, depth=2, title=f"{h.id}: {h.title}"),
            }
        )
    assumptions = []
    for a in case.assumptions:
        values = {k: config.get(k.split(".")[0], {}).get(k.split(".")[1], "?") for k in a.keys}
        assumptions.append(
            {
                "id": a.id,
                "title": a.title,
                "statement": a.statement,
                "values": values,
                "used_by": a.used_by,
                "watch": a.watch,
                "monitor": a.monitor,
                "how": a.how,
                "status": argument.nodes[a.id].status,
            }
        )
    top = argument.nodes[TOP]
    return CaseView(
        render_svg(argument, TOP, depth=2, title="Top goal, strategy and hazards"),
        top.status,
        hazards,
        assumptions,
        to_gsn2x(argument),
    )


def expected_refutations(bundle: Bundle) -> list[dict[str, Any]]:
    """Every SMT obligation attached as informative (``required=False``): expected outcomes
    such as a weakened model refuted, never part of a requirement's verdict."""
    out = []
    for item in bundle.tests:
        for d in item.details:
            if d["type"] == "smt" and not d["required"]:
                out.append(
                    {
                        "test": item.nodeid,
                        "requirements": list(item.requirement_ids),
                        "name": d["name"],
                        "verdict": d["verdict"],
                        "statement": d["statement"],
                    }
                )
    return out


_SUMMARY = jinja2.Environment(
    loader=jinja2.PackageLoader("evidence", "templates"),
    autoescape=jinja2.select_autoescape(["html", "j2"]),
    undefined=jinja2.StrictUndefined,
    trim_blocks=True,
    lstrip_blocks=True,
)


def render_summary(bundle: Bundle) -> str:
    """The one-page summary an assessor prints: verdict, scope, hazards, assumptions, what
    blocks, where the evidence is (self-contained HTML, A4 portrait)."""
    view = case_view(bundle)
    summary = bundle.summary
    return _SUMMARY.get_template("summary.html.j2").render(
        b=bundle,
        s=summary,
        p=bundle.provenance,
        view=view,
        refutations=expected_refutations(bundle),
        not_met=[r for r in bundle.requirements if r.verdict == "NOT MET"],
    )
