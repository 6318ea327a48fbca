"""Scenario simulator: warehouse and apron worlds, ray-cast LiDAR, ground truth (SR-SIM-*).

``shapes`` outlines and distances; ``objects`` the object models (cited footprints);
``motion`` profiles and trajectories; ``layouts`` static structure; ``world`` the posed world;
``raycast`` the vectorized caster; ``lidar`` beam layouts and the sensor model (returns
:class:`pipeline.types.Scan`); ``truth`` labels and per-scan ground truth; ``ego`` the robot
and its speed-policy interface; ``simulation`` the closed loop; ``history`` the bounded
records of long runs; ``scenarios`` and
``encounters`` the named and random scenarios; ``dataset`` the training-data file; ``plot``
and ``cli`` the ``safecase sim`` commands.
"""
