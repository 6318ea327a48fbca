"""Collision geometry: convex polygons, SAT, contact, swept paths, envelopes, costmap (SR-SAT-*).

:mod:`.polygons` (validation, batched hulls, bounds), :mod:`.sat` (separating-axis checks),
:mod:`.contact` (penetration and separation), :mod:`.swept` (swept volumes and the planner's
check), :mod:`.path` (free distance along the robot's path), :mod:`.envelopes` (predicted
regions grown by body and margin) and :mod:`.costmap` (conservative rasterization).
"""
