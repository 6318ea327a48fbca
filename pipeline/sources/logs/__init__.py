"""Recorded logs: ROS 1 and ROS 2 bags and MCAP (rosbags), CARMEN, BreezySLAM.

:class:`~.source.LogSource` turns any of them into frames (scans, odometry poses, the stamp rule
of :mod:`.stamps`); :mod:`.bags` and :mod:`.text` are the readers. Errors:
:class:`~.text.LogFormatError` (a file that does not follow its format) and
:class:`~.stamps.LogStampError` (stamps a tracker cannot use).
"""
