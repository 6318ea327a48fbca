"""Shape estimation: the outline of each cluster (convex hull, oriented box) (SR-TRK-2).

:mod:`.box` fits minimum-area oriented boxes by rotating calipers over each cluster's hull.
"""
