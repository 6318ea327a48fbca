"""evidence: the pytest plugin, schema, reports and signed manifests of safecase.

``evidence`` reports: it turns test, property, proof and benchmark outcomes into per-requirement
verdicts and a signed bundle an assessor can check. Tests attach details through
:func:`evidence.record.current` or the ``evidence`` fixture.
"""

from evidence.record import Recorder, current

__all__ = ["Recorder", "current"]
