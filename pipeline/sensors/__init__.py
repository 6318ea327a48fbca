"""Front-ends of the sensors beside the primary LiDAR: the thermal camera's geometry
(:mod:`pipeline.sensors.camera`), its detector (:mod:`pipeline.sensors.thermal`) and the
connected-components labelling it uses (:mod:`pipeline.sensors.components`)."""
