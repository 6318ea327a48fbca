"""The safety argument in Goal Structuring Notation, built from this run's evidence (SR-EVD-2).

:func:`build_argument` turns the catalogue's verdicts, the hazard log and the assumptions into a
GSN structure:

- the top goal, "the guarded robot does not collide while moving within its operating domain",
  in the context of the configuration and the hazard log, resting on the assumptions A-*;
- a strategy arguing over each identified hazard, one goal per hazard ("H-n is mitigated",
  in the context of its cause, situation and severity);
- under each hazard, one goal per requirement that mitigates it (the requirement's claim), each
  supported by one solution: that requirement's evidence items of this run.

Every node carries a status from this run: ``ok`` (SATISFIED), ``bad`` (VIOLATED, NOT MET),
``warn`` (NOT EVIDENCED; an assumption not monitored), ``planned``, or ``unjudged`` (outside a
slice). A hazard's goal is as bad as the worst claimed requirement under it, so a failing item
turns its whole branch red; a requirement NOT MET (built, its target not reached) leaves the
hazard open (amber). :func:`to_gsn2x` writes the structure in gsn2x's YAML (node IDs carry the
GSN prefix: G goal, S strategy, Sn solution, C context, A assumption), which gsn2x renders and
:func:`read_gsn2x` reads back; :mod:`evidence.gsn_svg` draws it.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from typing import Any

from evidence.model import Bundle, RequirementResult
from evidence.safety_case import SafetyCase

__all__ = ["TOP", "Argument", "Node", "build_argument", "read_gsn2x", "to_gsn2x"]

TOP = "G-top"
_RANK = {"ok": 0, "unjudged": 0, "planned": 0, "warn": 1, "bad": 2}
_VERDICT_STATUS = {
    "SATISFIED": "ok",
    "VIOLATED": "bad",
    "NOT MET": "bad",
    "NOT EVIDENCED": "warn",
    "PLANNED": "planned",
}


@dataclass(frozen=True, slots=True)
class Node:
    """One GSN element: ``kind`` is goal, strategy, solution, context or assumption."""

    id: str
    kind: str
    text: str
    status: str = "ok"
    supported_by: tuple[str, ...] = ()
    in_context_of: tuple[str, ...] = ()
    url: str = ""


@dataclass(frozen=True)
class Argument:
    """The nodes by ID (top goal :data:`TOP`) and the hazards in order."""

    nodes: dict[str, Node]
    hazard_goals: tuple[str, ...] = field(default_factory=tuple)

    def children(self, node_id: str) -> tuple[str, ...]:
        """The nodes supporting ``node_id``."""
        return self.nodes[node_id].supported_by


def _worst(statuses: list[str]) -> str:
    return max(statuses, key=lambda s: _RANK[s], default="ok")


def _requirement_status(result: RequirementResult, judged: bool) -> str:
    return _VERDICT_STATUS[result.verdict] if judged else "unjudged"


def build_argument(bundle: Bundle, case: SafetyCase, config: dict[str, Any]) -> Argument:
    """The GSN structure of this run (module docstring); ``config`` is the configuration as
    recorded in the bundle's provenance (section -> key -> value)."""
    results = {r.id: r for r in bundle.requirements}
    judged = set(bundle.summary["judged_requirements"])
    nodes: dict[str, Node] = {}
    for a in case.assumptions:
        values = ", ".join(f"{k} = {_lookup(config, k)}" for k in a.keys)
        watched = f"watched by {a.monitor}" if a.watch == "monitor" else a.watch
        if a.watch == "config":
            watched = "checked when the configuration loads"
        nodes[a.id] = Node(
            a.id,
            "assumption",
            f"{a.id} {a.title}: {a.statement} ({values}; {watched})",
            "ok" if a.watched else "warn",
        )
    hazard_goals = []
    for h in case.hazards:
        req_goals = []
        for req_id in h.mitigated_by:
            result = results.get(req_id)
            if result is None:
                continue
            goal_id, solution_id = f"G-{req_id}", f"Sn-{req_id}"
            status = _requirement_status(result, req_id in judged)
            n = len(result.evidence)
            passed = sum(result.passing.values())
            nodes[solution_id] = Node(
                solution_id,
                "solution",
                f"{req_id} evidence: {n} item(s), {passed} passing toward the minimum",
                status,
                url=f"#{req_id}",
            )
            nodes[goal_id] = Node(
                goal_id,
                "goal",
                f"{req_id} ({result.status}, {result.verdict}): {result.claim}",
                status,
                supported_by=(solution_id,),
                url=f"#{req_id}",
            )
            req_goals.append(goal_id)
        # A claimed requirement carries its status up; an unmet one (built, target not
        # reached) leaves the hazard open (amber), not failed; a planned one adds nothing.
        claimed = [
            nodes[g].status if results[g[2:]].status == "claimed" else "warn"
            for g in req_goals
            if results[g[2:]].status != "planned"
            and (results[g[2:]].status == "claimed" or nodes[g].status == "bad")
        ]
        context_id, goal_id = f"C-{h.id}", f"G-{h.id}"
        nodes[context_id] = Node(
            context_id,
            "context",
            f"{h.id} ({h.severity}): {h.cause} Situation: {h.situation}",
            "ok",
        )
        nodes[goal_id] = Node(
            goal_id,
            "goal",
            f"{h.id} is mitigated: {h.title}",
            _worst(claimed),
            supported_by=tuple(req_goals),
            in_context_of=(context_id,),
            url=f"#hazard-{h.id}",
        )
        hazard_goals.append(goal_id)
    top_status = _worst([nodes[g].status for g in hazard_goals])
    nodes["S-hazards"] = Node(
        "S-hazards",
        "strategy",
        f"Argument over each identified hazard ({len(hazard_goals)} in the hazard log)",
        top_status,
        supported_by=tuple(hazard_goals),
    )
    provenance = bundle.provenance
    nodes["C-domain"] = Node(
        "C-domain",
        "context",
        "Operating domain and parameters: configuration "
        f"{str(provenance.get('config_hash', ''))[:16]} "
        f"({provenance.get('config_path', '')}); hazard log {case.path.rsplit('/', 1)[-1]}",
        "ok",
    )
    nodes[TOP] = Node(
        TOP,
        "goal",
        "The guarded robot does not collide while moving within its operating domain",
        top_status,
        supported_by=("S-hazards",),
        in_context_of=("C-domain", *(a.id for a in case.assumptions)),
    )
    return Argument(nodes, tuple(hazard_goals))


def _lookup(config: dict[str, Any], dotted: str) -> Any:
    section, _, key = dotted.partition(".")
    return config.get(section, {}).get(key, "?")


def to_gsn2x(argument: Argument) -> str:
    """The argument as gsn2x YAML: one mapping per node, keyed by its prefixed ID."""
    from ruamel.yaml import YAML

    data: dict[str, Any] = {}
    for node in argument.nodes.values():
        entry: dict[str, Any] = {"text": node.text}
        if node.supported_by:
            entry["supportedBy"] = list(node.supported_by)
        if node.in_context_of:
            entry["inContextOf"] = list(node.in_context_of)
        if node.url:
            entry["url"] = node.url
        entry["classes"] = [node.status]
        data[node.id] = entry
    yaml = YAML(typ="safe", pure=True)
    yaml.default_flow_style = False
    stream = io.StringIO()
    stream.write("# safecase safety argument (GSN), gsn2x YAML; statuses from this run\n")
    yaml.dump(data, stream)
    return stream.getvalue()


def read_gsn2x(text: str) -> dict[str, dict[str, Any]]:
    """Parse gsn2x YAML (a mapping of node ID to attributes)."""
    from ruamel.yaml import YAML

    loaded = YAML(typ="safe", pure=True).load(text)
    if not isinstance(loaded, dict):
        raise ValueError("a gsn2x document is a mapping of node IDs")
    return loaded
