"""``python -m evidence.cli`` runs the ``safecase`` command line."""

from evidence.cli.main import main

main()
