"""The safety formulas, each one definition read by the runtime and by z3 (SR-STOP-*, SR-FUS-*).

:mod:`.stopping` (stopping distance, margin tiers, safe speed), :mod:`.readings` (piecewise
helpers that keep a formula one definition), :mod:`.governor` (free distance to command),
:mod:`.monitors` (staleness, clock, driver, deadline, operating domain) and :mod:`.decision`
(the fold of governor and monitors into one command).
"""
