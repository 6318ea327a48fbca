"""Draw a GSN argument as a self-contained SVG (no scripts, no fonts fetched, no network).

Shapes follow the GSN standard: a goal is a rectangle, a strategy a parallelogram, a solution a
circle, a context a rounded rectangle, an assumption an ellipse marked "A". Solid arrows are
"supported by", hollow ones "in context of". Fill and stroke give each node's status in this
run: green satisfied, red failing (its whole branch red above it), amber not evidenced or not
monitored, grey planned, dashed not judged (outside a slice). Nodes with a target link to their
section of the report.

The layout is layered: the root on top with its context and assumptions on either side in
the same row (more than two assumptions are drawn as one node that links to the assumptions
table), each level of "supported by" below it.
"""

from __future__ import annotations

import textwrap
from dataclasses import dataclass
from xml.sax.saxutils import escape, quoteattr

from evidence.argument import Argument, Node

__all__ = ["render_svg"]

_COLOURS = {
    "ok": ("#1a7f37", "#dafbe1"),
    "bad": ("#cf222e", "#ffebe9"),
    "warn": ("#9a6700", "#fff8c5"),
    "planned": ("#57606a", "#f6f8fa"),
    "unjudged": ("#8c959f", "#ffffff"),
}
_W, _GAP_X, _GAP_Y, _LINE, _PAD = 200, 18, 46, 14, 8
_SIDE_W = 300


@dataclass(frozen=True)
class _Box:
    node: Node
    x: float
    y: float
    w: float
    h: float
    lines: tuple[str, ...]


def _lines(node: Node, width: float) -> tuple[str, ...]:
    chars = max(int(width / 6.6), 10)
    wrapped = textwrap.wrap(node.text, chars) or [""]
    most = 4 if node.kind == "solution" else 7
    if len(wrapped) > most:
        wrapped = [*wrapped[: most - 1], wrapped[most - 1][: chars - 1] + "\u2026"]
    return (node.id, *wrapped)


def _size(node: Node, width: float) -> tuple[float, float, tuple[str, ...]]:
    if node.kind == "solution":
        lines = _lines(node, 104)
        d = max(120.0, _LINE * len(lines) + 30)
        return d, d, lines
    lines = _lines(node, width - 2 * _PAD - (24 if node.kind == "strategy" else 0))
    h = _LINE * len(lines) + 2 * _PAD + (10 if node.kind == "assumption" else 0)
    return width, h, lines


def _levels(argument: Argument, root: str, depth: int) -> list[list[str]]:
    levels, seen = [[root]], {root}
    for _ in range(depth):
        nxt = []
        for node_id in levels[-1]:
            for child in argument.children(node_id):
                if child not in seen:
                    seen.add(child)
                    nxt.append(child)
        if not nxt:
            break
        levels.append(nxt)
    return levels


def _shape(box: _Box) -> str:
    stroke, fill = _COLOURS[box.node.status]
    dash = ' stroke-dasharray="5,3"' if box.node.status == "unjudged" else ""
    style = f'fill="{fill}" stroke="{stroke}" stroke-width="1.6"{dash}'
    x, y, w, h = box.x, box.y, box.w, box.h
    kind = box.node.kind
    if kind == "strategy":
        pts = f"{x + 12},{y} {x + w},{y} {x + w - 12},{y + h} {x},{y + h}"
        return f"<polygon points={quoteattr(pts)} {style}/>"
    if kind == "solution":
        return f'<circle cx="{x + w / 2}" cy="{y + h / 2}" r="{w / 2}" {style}/>'
    if kind == "assumption":
        return (
            f'<ellipse cx="{x + w / 2}" cy="{y + h / 2}" rx="{w / 2}" ry="{h / 2 + 6}" {style}/>'
            f'<text x="{x + w - 6}" y="{y + h + 4}" font-weight="bold">A</text>'
        )
    radius = 16 if kind == "context" else 0
    return f'<rect x="{x}" y="{y}" width="{w}" height="{h}" rx="{radius}" {style}/>'


def _text(box: _Box) -> str:
    centre = box.node.kind in ("solution", "assumption")
    top = box.y + (box.h - _LINE * len(box.lines)) / 2 + 11 if centre else box.y + _PAD + 11
    x = box.x + box.w / 2 if centre else box.x + _PAD + (12 if box.node.kind == "strategy" else 0)
    anchor = ' text-anchor="middle"' if centre else ""
    out = []
    for i, line in enumerate(box.lines):
        weight = ' font-weight="bold"' if i == 0 else ""
        out.append(f'<text x="{x}" y="{top + i * _LINE}"{anchor}{weight}>{escape(line)}</text>')
    return "".join(out)


def _node(box: _Box) -> str:
    body = _shape(box) + _text(box)
    if box.node.url:
        return f"<a href={quoteattr(box.node.url)}>{body}</a>"
    return body


def _edge(parent: _Box, child: _Box, hollow: bool) -> str:
    if hollow:  # context beside its goal: from the goal's facing edge to the node's
        right = child.x > parent.x
        x1 = parent.x + parent.w if right else parent.x
        x2 = child.x if right else child.x + child.w
        y1 = y2 = parent.y + parent.h / 2
    else:
        x1, y1 = parent.x + parent.w / 2, parent.y + parent.h
        x2, y2 = child.x + child.w / 2, child.y
    marker = "hollow" if hollow else "solid"
    return (
        f'<line x1="{x1}" y1="{y1}" x2="{x2}" y2="{y2}" stroke="#57606a" '
        f'stroke-width="1.2" marker-end="url(#{marker})"/>'
    )


def _context(argument: Argument, root: str) -> list[Node]:
    """The nodes drawn beside ``root``: its contexts, and its assumptions (one summary node
    linking to the assumptions table when there are more than two)."""
    nodes = [argument.nodes[n] for n in argument.nodes[root].in_context_of]
    assumptions = [n for n in nodes if n.kind == "assumption"]
    if len(assumptions) <= 2:
        return nodes
    watched = sum(1 for a in assumptions if a.status == "ok")
    summary = Node(
        "A-1..A-" + str(len(assumptions)),
        "assumption",
        f"{len(assumptions)} assumptions the proofs rest on: {watched} watched at run time, "
        f"{len(assumptions) - watched} not monitored (see the assumptions table)",
        "ok" if watched == len(assumptions) else "warn",
        url="#assumptions",
    )
    return [n for n in nodes if n.kind != "assumption"] + [summary]


def render_svg(argument: Argument, root: str, *, depth: int = 2, title: str = "") -> str:
    """An SVG of ``root`` and ``depth`` levels of support below it, with the root's context."""
    levels = _levels(argument, root, depth)
    sized = {n: _size(argument.nodes[n], _W) for level in levels for n in level}
    context = _context(argument, root)
    side_sizes = [_size(n, _SIDE_W) for n in context]
    right, left = side_sizes[0::2], side_sizes[1::2]
    side_w = [sum(s[0] + 60 for s in half) for half in (left, right)]
    row_widths = [sum(sized[n][0] for n in level) + _GAP_X * (len(level) - 1) for level in levels]
    row_widths[0] += 2 * max(side_w)
    width = max(row_widths, default=_W)
    boxes: dict[str, _Box] = {}
    y = 30.0 if title else 10.0
    for i, (level, row_width) in enumerate(zip(levels, row_widths, strict=True)):
        x = (width - row_width) / 2 + 10 + (max(side_w) if i == 0 else 0)
        height = max([sized[n][1] for n in level] + ([s[1] for s in side_sizes] if i == 0 else []))
        for n in level:
            w, h, lines = sized[n]
            boxes[n] = _Box(argument.nodes[n], x, y + (height - h) / 2, w, h, lines)
            x += w + _GAP_X
        y += height + _GAP_Y
    top = boxes[root]
    side = []
    for k, node in enumerate(context):
        w, h, lines = side_sizes[k]
        ahead = context[k % 2 : k : 2]  # the nodes already placed on the same side
        offset = sum(side_sizes[context.index(a)][0] + 60 for a in ahead) + 60
        x = top.x + top.w + offset if k % 2 == 0 else top.x - offset - w
        boxes[node.id] = _Box(node, x, top.y + (top.h - h) / 2, w, h, lines)
        side.append(node.id)
    total_w = width + 20
    total_h = y + 10
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{total_w:.0f}" height="{total_h:.0f}" '
        f'viewBox="0 0 {total_w:.0f} {total_h:.0f}" font-family="sans-serif" font-size="11" '
        f'role="img" aria-label={quoteattr(title or root)}>',
        "<defs>"
        '<marker id="solid" markerWidth="10" markerHeight="8" refX="9" refY="4" orient="auto">'
        '<path d="M0,0 L10,4 L0,8 z" fill="#57606a"/></marker>'
        '<marker id="hollow" markerWidth="10" markerHeight="8" refX="9" refY="4" orient="auto">'
        '<path d="M0,0 L10,4 L0,8 z" fill="#ffffff" stroke="#57606a"/></marker></defs>',
    ]
    if title:
        parts.append(
            f'<text x="10" y="18" font-size="13" font-weight="bold">{escape(title)}</text>'
        )
    for level in levels[:-1]:
        for n in level:
            for child in argument.children(n):
                if child in boxes and child not in side:
                    parts.append(_edge(boxes[n], boxes[child], hollow=False))
    for n in side:
        parts.append(_edge(top, boxes[n], hollow=True))
    parts.extend(_node(box) for box in boxes.values())
    parts.append("</svg>")
    return "".join(parts)
