"""Clustering: scan points into DBSCAN clusters with their geometry and ends (SR-TRK-2).

:mod:`.dbscan` partitions the points and measures each kept cluster; :mod:`.ends` finds the
first and last point of each cluster in the sweep and whether the scanner saw past them.
"""
