"""Classifier training from simulator runs: labelled rows, data plans, the seeded trainer.

:mod:`.data` runs a simulation through the perception chain and labels its rows from the
ground truth; :mod:`.plan` holds the data plans and their block cache; :mod:`.train` fits and
writes the model (SR-CLS-2, SR-CLS-3).
"""
