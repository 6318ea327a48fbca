"""Structured details that a test attaches to its evidence (requirement SR-EVD-*).

Tests reach the recorder through the session-scoped ``evidence`` fixture or through
:func:`current` (usable inside ``@given`` bodies and helpers). Both resolve to the test that is
running now, so Hypothesis' function-scoped-fixture health check does not apply and every
example of a property adds to the same record.

Kinds of detail: an SMT obligation (:meth:`Recorder.smt`), counters (:meth:`Recorder.count`),
samples such as latencies (:meth:`Recorder.samples`), tables, plots, notes, and session-wide
provenance (:meth:`Recorder.provenance`, e.g. a model hash or where the latency bound came
from).
"""

from __future__ import annotations

import base64
import io
import math
from collections.abc import Iterable, Mapping, Sequence
from fractions import Fraction
from typing import Any

import numpy as np

__all__ = ["Recorder", "current"]

_MAX_RAW_SAMPLES = 20_000


class _ItemRecord:
    """What one test attached; filled while it runs, read by the plugin afterwards."""

    def __init__(self, nodeid: str) -> None:
        self.nodeid = nodeid
        self.details: list[dict[str, Any]] = []
        self.counters: dict[str, dict[str, float]] = {}
        self.kind: str | None = None


class Recorder:
    """Facade over the running test's record, plus the session's provenance.

    Records and sessions are stacks so that a test which itself runs pytest in-process
    (pytester) gets its own record back when the inner session ends.
    """

    def __init__(self) -> None:
        self._items: list[_ItemRecord] = []
        self._sessions: list[dict[str, Any]] = [{}]

    # -- plumbing used by the plugin -------------------------------------------------------
    def push_session(self) -> None:
        """Start a session's provenance."""
        self._sessions.append({})

    def pop_session(self) -> None:
        """End a session's provenance."""
        if len(self._sessions) > 1:
            self._sessions.pop()

    @property
    def session_provenance(self) -> dict[str, Any]:
        """Provenance recorded by tests of the innermost running session."""
        return self._sessions[-1]

    def begin(self, nodeid: str) -> None:
        """Start recording for the test ``nodeid``."""
        self._items.append(_ItemRecord(nodeid))

    def end(self) -> _ItemRecord | None:
        """Stop recording for the innermost test; return what it attached."""
        return self._items.pop() if self._items else None

    def peek(self) -> _ItemRecord | None:
        """The innermost running test's record, if any."""
        return self._items[-1] if self._items else None

    @property
    def _record(self) -> _ItemRecord:
        if not self._items:
            raise RuntimeError("evidence: no test is running; attach details from inside a test")
        return self._items[-1]

    def replay(
        self,
        details: list[dict[str, Any]],
        counters: Mapping[str, Mapping[str, float]],
        kind: str | None,
        provenance: Mapping[str, Any],
    ) -> None:
        """Attach to the running test what the same test body recorded in another process
        (properties.ahead): its details in order, its counters added, its kind when declared
        and its session provenance."""
        record = self._record
        record.details.extend(details)
        for group, values in counters.items():
            mine = record.counters.setdefault(group, {})
            for key, n in values.items():
                mine[key] = mine.get(key, 0) + n
        if kind is not None:
            record.kind = kind
        self.session_provenance.update(provenance)

    # -- what tests call -------------------------------------------------------------------
    def kind(self, kind: str) -> None:
        """Declare the evidence kind of this test when inference would get it wrong."""
        self._record.kind = kind

    def smt(
        self,
        name: str,
        verdict: str,
        smtlib: str,
        *,
        model: Mapping[str, Fraction | float | int | str] | None = None,
        solver: str = "",
        time_s: float = 0.0,
        required: bool = True,
        statement: str = "",
    ) -> None:
        """Attach an SMT obligation with its verdict (PROVED, REFUTED or UNKNOWN).

        ``required=True`` (the default) makes the test count as failed evidence unless the
        verdict is PROVED, whatever the test asserts; use ``required=False`` for obligations
        that are expected to be refuted (e.g. a finding about someone else's numbers).
        ``model`` values are shown both exactly (rationals) and as floats.
        """
        if verdict not in ("PROVED", "REFUTED", "UNKNOWN"):
            raise ValueError(f"smt verdict {verdict!r}: expected PROVED, REFUTED or UNKNOWN")
        shown: dict[str, dict[str, Any]] = {}
        for var, value in (model or {}).items():
            exact = value if isinstance(value, str) else str(Fraction(value))
            try:
                as_float = float(Fraction(exact))
            except (ValueError, ZeroDivisionError):
                as_float = math.nan
            shown[var] = {"exact": exact, "float": as_float}
        self._record.details.append(
            {
                "type": "smt",
                "name": name,
                "verdict": verdict,
                "statement": statement,
                "smtlib": smtlib,
                "model": shown,
                "solver": solver,
                "time_s": time_s,
                "required": required,
            }
        )
        if self._record.kind is None:
            self._record.kind = "proof"

    def count(self, group: str, key: str, n: float = 1) -> None:
        """Add ``n`` to counter ``key`` of ``group`` (e.g. disagreements by kind)."""
        counters = self._record.counters.setdefault(group, {})
        counters[key] = counters.get(key, 0) + n

    def counts(self, group: str, values: Mapping[str, float]) -> None:
        """Set several counters of ``group`` at once."""
        self._record.counters.setdefault(group, {}).update(values)

    def samples(self, name: str, values: Iterable[float], unit: str) -> None:
        """Attach samples (e.g. latencies) with their summary statistics."""
        array = np.asarray(list(values), dtype=np.float64)
        if array.size == 0:
            raise ValueError(f"samples {name!r}: no values")
        self._record.details.append(
            {
                "type": "samples",
                "name": name,
                "unit": unit,
                "n": int(array.size),
                "min": float(array.min()),
                "p50": float(np.percentile(array, 50)),
                "p99": float(np.percentile(array, 99)),
                "max": float(array.max()),
                "mean": float(array.mean()),
                "values": array[:_MAX_RAW_SAMPLES].tolist(),
            }
        )

    def table(
        self, name: str, columns: Sequence[str], rows: Sequence[Sequence[Any]], caption: str = ""
    ) -> None:
        """Attach a table (e.g. accuracy per class beside the published figures)."""
        width = len(columns)
        for row in rows:
            if len(row) != width:
                raise ValueError(f"table {name!r}: row {row!r} has {len(row)} cells, not {width}")
        self._record.details.append(
            {
                "type": "table",
                "name": name,
                "columns": list(columns),
                "rows": [list(r) for r in rows],
                "caption": caption,
            }
        )

    def plot(self, name: str, figure: Any, caption: str = "") -> None:
        """Attach a matplotlib figure (or PNG bytes); stored in the bundle and inlined in HTML."""
        if isinstance(figure, bytes | bytearray):
            png = bytes(figure)
        else:
            buffer = io.BytesIO()
            figure.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
            png = buffer.getvalue()
        if not png.startswith(b"\x89PNG"):
            raise ValueError(f"plot {name!r}: not PNG data")
        self._record.details.append(
            {
                "type": "plot",
                "name": name,
                "caption": caption,
                "png_base64": base64.b64encode(png).decode("ascii"),
            }
        )

    def note(self, text: str) -> None:
        """Attach a free-text observation."""
        self._record.details.append({"type": "note", "text": text})

    def provenance(self, key: str, value: Any) -> None:
        """Record session-wide provenance (a model hash, the latency bound's origin, ...)."""
        self.session_provenance[key] = value


_RECORDER = Recorder()


def current() -> Recorder:
    """The recorder of the running session (attaches to the test running now)."""
    return _RECORDER
