"""Adapters for the independent reference implementations, one module per family.

``geometry`` (python-fcl, shapely/GEOS), ``tracking`` (scikit-learn DBSCAN, filterpy),
``classify`` (xgboost's own predict). Nothing in the runtime imports these: they exist only
to check our code against code nobody here wrote.
"""
