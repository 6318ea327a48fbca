"""safety: decisions, from predicted obstacles to PROCEED / SLOW / STOP.

Stopping model, collision geometry, envelopes, governor, monitors, runtime and audit log;
the requirements catalogue (``requirements.toml``) and the ``safecase`` command line.
"""
