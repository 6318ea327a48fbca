"""The ``safecase`` command line: every command, imported by nothing.

It sits above every other layer (pipeline < safety < evidence < properties; an
import-linter contract keeps it so): :mod:`.main` is the entry point and holds certify,
evidence, config and requirements; :mod:`.run`, :mod:`.audit`, :mod:`.sim` and :mod:`.train`
hold the command groups of the same names.
"""
