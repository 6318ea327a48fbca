"""Rendering of an evidence bundle: HTML, Markdown, JUnit XML, SMT-LIB and plot files.

The HTML report is self-contained (inline CSS, plots as data URIs, no scripts, no external
assets) so it reads offline. :func:`write_bundle` writes every artifact, then the signed
manifest over all of them (SR-EVD-1).
"""

from __future__ import annotations

import base64
import re
import xml.etree.ElementTree as ET
from collections import Counter
from dataclasses import asdict
from pathlib import Path
from typing import Any

import jinja2
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from evidence.case_view import case_view, expected_refutations, render_summary
from evidence.manifest import write_manifest
from evidence.model import Bundle, EvidenceItem

__all__ = ["render_html", "render_junit", "render_markdown", "write_bundle"]


def _environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.PackageLoader("evidence", "templates"),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
    )


class _Attr(dict[str, Any]):
    """A dict whose keys read as attributes in templates (``t.kind``)."""

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError as exc:
            raise AttributeError(name) from exc


def _wrap(value: Any) -> Any:
    if isinstance(value, dict):
        return _Attr({k: _wrap(v) for k, v in value.items()})
    if isinstance(value, list):
        return [_wrap(v) for v in value]
    return value


def _test_view(item: EvidenceItem) -> _Attr:
    view: _Attr = _wrap(asdict(item))
    view["effective_outcome"] = item.effective_outcome
    return view


def render_html(bundle: Bundle) -> str:
    """The self-contained HTML report."""
    tests = {t.nodeid: _test_view(t) for t in bundle.tests}
    template = _environment().get_template("report.html.j2")
    return template.render(
        b=_wrap(bundle.to_dict()),
        s=_wrap(bundle.summary),
        p=_wrap(bundle.provenance),
        e=_wrap(bundle.environment),
        family_verdicts=bundle.family_verdicts(),
        tests_by_id=tests,
        unlinked=[tests[t.nodeid] for t in bundle.tests if not t.requirement_ids],
        planned_count=sum(1 for r in bundle.requirements if r.status == "planned"),
        view=case_view(bundle),
        refutations=expected_refutations(bundle),
    )


def _md_escape(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def render_markdown(bundle: Bundle) -> str:
    """A Markdown summary: verdicts per requirement, the matrix and the provenance."""
    s = bundle.summary
    p = bundle.provenance
    lines = [
        f"# safecase certification report: {s['certification']}",
        "",
        f"- created: {bundle.created_utc}; profile: `{bundle.profile}`",
        f"- commit: `{p['git']['commit']}`" + (" (dirty tree)" if p["git"]["dirty"] else ""),
        f"- project: {p['project']['name']} {p['project']['version']}"
        if "project" in p
        else "- project: not recorded",
        f"- config hash: `{p.get('config_hash', 'not recorded')}`",
        f"- tests: {s['tests']['passed']} passed, {s['tests']['failed']} failed, "
        f"{s['tests']['error']} errors, {s['tests']['skipped']} skipped",
        "- requirements: " + ", ".join(f"{v} {k}" for k, v in s["requirements"].items()),
        "",
    ]
    if bundle.selection is not None:
        sel = bundle.selection
        lines += [
            f"**A slice of the suite, not a certification:** {sel['expression']} selected "
            f"{sel['selected']} test(s) and left out {sel['deselected']}; only the "
            f"{len(s['judged_requirements'])} requirement(s) its tests touched are judged.",
            "",
        ]
    if s["blocking_requirements"]:
        lines += [f"**Blocking:** {', '.join(s['blocking_requirements'])}", ""]
    view = case_view(bundle)
    if view is not None:
        lines += [f"## Hazards (argument status: {view.status})", ""]
        lines += ["| hazard | severity | status | mitigated by |", "|---|---|---|---|"]
        for h in view.hazards:
            reqs = ", ".join(f"{r} {v}" for r, v in h["requirements"])
            lines.append(f"| {h['id']} {h['title']} | {h['severity']} | {h['status']} | {reqs} |")
        lines += ["", "| assumption | watched |", "|---|---|"]
        for a in view.assumptions:
            watched = f"monitor `{a['monitor']}`" if a["watch"] == "monitor" else a["watch"]
            lines.append(f"| {a['id']} {a['title']} | {watched} |")
        lines.append("")
    lines += [
        "## Traceability matrix",
        "",
        "| requirement | status | verdict | evidence | code |",
        "|---|---|---|---|---|",
    ]
    outcomes = {t.nodeid: t for t in bundle.tests}
    for r in bundle.requirements:
        evidence = (
            "<br>".join(
                f"{outcomes[n].effective_outcome} {outcomes[n].kind}: `{n}`" for n in r.evidence
            )
            or "none"
        )
        lines.append(
            f"| {r.id} | {r.status} | {r.verdict} | {evidence} | "
            + "<br>".join(f"`{c}`" for c in r.code)
            + " |"
        )
    lines += ["", "## Requirements", ""]
    for r in bundle.requirements:
        lines.append(f"### {r.id}: {r.verdict}")
        lines.append("")
        lines.append(_md_escape(r.claim))
        lines.append("")
        if r.missing:
            lines.append(f"Missing: {'; '.join(r.missing)}")
            lines.append("")
        for nodeid in r.evidence:
            item = outcomes[nodeid]
            lines.append(f"- {item.effective_outcome} ({item.kind}) `{nodeid}`")
            for detail in item.details:
                if detail["type"] == "smt":
                    lines.append(f"  - SMT {detail['name']}: {detail['verdict']}")
                    for var, value in detail["model"].items():
                        lines.append(f"    - `{var}` = {value['exact']} ({value['float']:.12g})")
            if item.hypothesis and item.hypothesis.get("falsifying_example"):
                lines.append("  - falsifying example:")
                lines.append("")
                lines.append("```")
                lines.append(item.hypothesis["falsifying_example"])
                lines.append("```")
        lines.append("")
    env = bundle.environment
    lines += [
        "## Environment",
        "",
        f"- Python {env['python']} on {env['platform']} ({env['cpu']}, {env['cpu_count']} CPUs)",
        f"- z3 {env['z3']}",
    ]
    lines += [f"- {k} {v}" for k, v in env["key_packages"].items()]
    return "\n".join(lines) + "\n"


def render_junit(bundle: Bundle) -> str:
    """JUnit XML with one testcase per item and its requirement IDs as properties, and the
    certification verdict: a property of the suite, and one failed testcase (classname
    ``requirements``) per judged requirement that blocks it, so a dashboard counts it."""
    outcomes = Counter(t.effective_outcome for t in bundle.tests)
    summary = bundle.summary
    blocking = {r.id: r for r in bundle.requirements if r.id in summary["blocking_requirements"]}
    suite = ET.Element(
        "testsuite",
        name="safecase",
        tests=str(len(bundle.tests) + len(blocking)),
        failures=str(outcomes.get("failed", 0) + len(blocking)),
        errors=str(outcomes.get("error", 0)),
        skipped=str(outcomes.get("skipped", 0)),
        time=f"{sum(t.duration_s for t in bundle.tests):.3f}",
        timestamp=bundle.created_utc,
    )
    props = ET.SubElement(suite, "properties")
    for key in ("config_hash",):
        ET.SubElement(props, "property", name=key, value=str(bundle.provenance.get(key)))
    ET.SubElement(props, "property", name="profile", value=bundle.profile)
    ET.SubElement(props, "property", name="certification", value=summary["certification"])
    ET.SubElement(props, "property", name="scope", value=summary["scope"])
    for req_id, result in blocking.items():
        case = ET.SubElement(suite, "testcase", classname="requirements", name=req_id, time="0")
        why = "; ".join(result.missing) or f"{len(result.failures)} failing item(s)"
        ET.SubElement(case, "failure", message=f"{result.verdict}: {why}"[:500]).text = result.claim
    for item in bundle.tests:
        module, _, name = item.nodeid.partition("::")
        case = ET.SubElement(
            suite,
            "testcase",
            classname=module.removesuffix(".py").replace("/", "."),
            name=name or module,
            time=f"{item.duration_s:.3f}",
        )
        if item.requirement_ids:
            case_props = ET.SubElement(case, "properties")
            for req_id in item.requirement_ids:
                ET.SubElement(case_props, "property", name="requirement", value=req_id)
            ET.SubElement(case_props, "property", name="kind", value=item.kind)
        outcome = item.effective_outcome
        if outcome == "failed":
            ET.SubElement(case, "failure", message=item.message[:500]).text = item.longrepr
        elif outcome == "error":
            ET.SubElement(case, "error", message=item.message[:500]).text = item.longrepr
        elif outcome == "skipped":
            ET.SubElement(case, "skipped", message=item.message[:500])
    ET.indent(suite)
    return ET.tostring(suite, encoding="unicode", xml_declaration=True) + "\n"


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_")[:120] or "item"


def write_bundle(out_dir: Path, bundle: Bundle, key: Ed25519PrivateKey) -> list[Path]:
    """Write every artifact of ``bundle`` into ``out_dir`` and sign the manifest."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    view = case_view(bundle)
    artifacts = [
        ("evidence.json", bundle.to_json()),
        ("report.html", render_html(bundle)),
        ("report.md", render_markdown(bundle)),
        ("junit.xml", render_junit(bundle)),
        ("summary.html", render_summary(bundle)),
    ]
    if view is not None:
        artifacts += [("argument.gsn.yaml", view.gsn_yaml), ("argument.svg", view.top_svg)]
    for name, text in artifacts:
        path = out_dir / name
        path.write_text(text, encoding="utf-8")
        written.append(path)
    for item in bundle.tests:
        for detail in item.details:
            if detail["type"] == "smt":
                path = out_dir / "smt" / f"{_slug(item.nodeid)}--{_slug(detail['name'])}.smt2"
                path.parent.mkdir(exist_ok=True)
                path.write_text(detail["smtlib"], encoding="utf-8")
                written.append(path)
            elif detail["type"] == "plot":
                path = out_dir / "plots" / f"{_slug(item.nodeid)}--{_slug(detail['name'])}.png"
                path.parent.mkdir(exist_ok=True)
                path.write_bytes(base64.b64decode(detail["png_base64"]))
                written.append(path)
    written.append(write_manifest(out_dir, bundle.provenance, key))
    return written
