"""Classification of tracks: the verified model file and its fast evaluator (SR-CLS-1, -3).

:mod:`.model` loads and hash-checks the XGBoost model and classifies feature rows;
:mod:`.trees` evaluates the tree ensemble in vectorised numpy.
"""
