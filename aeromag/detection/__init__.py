"""Detectors of magnetic interference and faults, all returning one result type.

:class:`~aeromag.detection.alarms.Alarms` is the result every detector returns (the heading
detector, the particle-filter detector, the track-deviation detector), so that ``track`` and
``detect`` combine and report them the same way.
"""
