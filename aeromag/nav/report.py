"""The report of a navigation run (OUT.json of ``aeromag navigate``).

:func:`aeromag.nav.navigate` builds a :class:`NavReport`; the track check's navigation, the
workflow and the command line read its attributes, and ``to_dict()`` is the JSON the command
writes (``from_dict()`` reads it back).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["NavReport"]

#: Keys of OUT.json held by :class:`NavReport` fields, in the file's order.
_KEYS = ("gps", "settings", "innovations", "mean_nis", "reference_field", "ground_d_m",
         "mag_bias_deg", "imu_interval_s", "warnings")


@dataclass(kw_only=True)
class NavReport:
    """What a navigation run used and how well each sensor fitted.

    Attributes
    ----------
    gps : dict
        ``mode``, ``origin`` (lat, lon, alt), ``origin_from``, ``intervals`` (the GNSS
        intervals used, s), ``n_fixes_in_log``, ``n_fixes_used``, ``n_fixes_fused``.
    settings : dict
        The filter's settings (:meth:`~aeromag.nav.NavConfig.as_dict`) with ``sensors``,
        ``states`` and ``noise_used``.
    innovations : dict
        Sensor -> its innovation statistics (``n_fused``, ``n_rejected``, ``dof``,
        ``mean_nis``, ``mean_nis_per_dof``, ``nis_band``, ...): one entry per sensor model.
    mean_nis : dict
        Sensor -> mean normalised innovation squared (None when nothing was fused).
    reference_field : dict
        ``ned_nT``, ``declination_deg``, ``from_log``, ``declination_from`` (and, from the
        workflow, ``source``: the reference field's description).
    ground_d_m : float or None
        Height of the ground below the origin, m (down positive).
    mag_bias_deg : float or None
        Estimated magnetometer heading bias, degrees.
    imu_interval_s : float or None
        Median IMU sample interval, s.
    warnings : list of str
        The run's warnings.
    input : str or None
        The log's file name (set by the workflow).
    extra : dict
        Keys of a read report that no field holds (written back after the known ones).
    """

    gps: dict[str, Any] = field(default_factory=dict)
    settings: dict[str, Any] = field(default_factory=dict)
    innovations: dict[str, dict[str, Any]] = field(default_factory=dict)
    mean_nis: dict[str, float | None] = field(default_factory=dict)
    reference_field: dict[str, Any] = field(default_factory=dict)
    ground_d_m: float | None = None
    mag_bias_deg: float | None = None
    imu_interval_s: float | None = None
    warnings: list[str] = field(default_factory=list)
    input: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def sensors(self) -> list[str]:
        """The measurement models the run used (``settings["sensors"]``)."""
        return list(self.settings.get("sensors", []))

    def to_dict(self) -> dict[str, Any]:
        """The report as OUT.json holds it."""
        out = {key: getattr(self, key) for key in _KEYS}
        if self.input is not None:
            out["input"] = self.input
        out.update(self.extra)
        return out

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> NavReport:
        """Read a report written by :meth:`to_dict` (an OUT.json of ``aeromag navigate``)."""
        known = (*_KEYS, "input")
        return cls(**{k: d[k] for k in known if k in d},
                   extra={k: v for k, v in d.items() if k not in known})
