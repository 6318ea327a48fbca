"""``python -m safety`` runs the ``safecase`` command line."""

from safety.cli import main

main()
