"""The tamper-evident audit log of every cycle (SR-AUD-1, SR-AUD-2).

:mod:`.log` writes the hash-chained records and the head anchor; :mod:`.verify` checks a log;
:mod:`.replay` recomputes every recorded decision.
"""
