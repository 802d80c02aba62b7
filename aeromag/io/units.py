"""Units: field units to nT and time units to s, the one table column maps and files use."""

from __future__ import annotations

from ..conventions import FLUX_COLUMNS
from ..errors import InputError

__all__ = ["FIELD_UNITS_TO_NT", "TIME_UNITS_PER_S", "UNIT_GROUPS",
           "time_ticks", "unit_factor"]

#: Factors that convert a magnetic field unit to nT.
FIELD_UNITS_TO_NT: dict[str, float] = {
    "pt": 1.0e-3,
    "nt": 1.0,
    "ut": 1.0e3,
    "\u00b5t": 1.0e3,  # micro sign (U+00B5)
    "\u03bct": 1.0e3,  # Greek small letter mu (U+03BC): both are written for microtesla
    "mt": 1.0e6,
    "g": 1.0e5,
    "gauss": 1.0e5,
    "mg": 1.0e2,
    "t": 1.0e9,
}

#: Ticks per second of the time units (``units={"time": "ms"}``): seconds = value / ticks
#: (a division, exact for whole milliseconds: 1700000000100 ms is 1700000000.1 s).
TIME_UNITS_PER_S: dict[str, float] = {
    "s": 1.0,
    "ms": 1.0e3,
    "us": 1.0e6,
    "\u00b5s": 1.0e6,
    "\u03bcs": 1.0e6,
    "ns": 1.0e9,
}

#: Unit groups: a key of ``units`` may name a group or a single column.
UNIT_GROUPS: dict[str, tuple[str, ...]] = {
    "flux": FLUX_COLUMNS,
    "mag": ("mag",),
}


def unit_factor(unit: str, *, what: str = "units") -> float:
    """Return the factor that converts a field unit to nT.

    Parameters
    ----------
    unit : str
        One of ``pT``, ``nT``, ``uT`` (``µT``, with either the micro sign U+00B5 or the
        Greek mu U+03BC), ``mT``, ``G`` (``gauss``), ``mG``, ``T`` (case-insensitive).
    what : str
        Context quoted in the error message.

    Returns
    -------
    float
        Multiply values in ``unit`` by this to get nT.
    """
    key = unit.strip().lower()
    if key not in FIELD_UNITS_TO_NT:
        known = ", ".join(["pT", "nT", "uT", "mT", "G", "mG", "T"])
        raise InputError(f"{what}: unknown field unit {unit!r}; use one of {known}")
    return FIELD_UNITS_TO_NT[key]


def time_ticks(unit: str, *, what: str = "units time") -> float:
    """Return the ticks per second of a time unit (divide by it to get seconds).

    Parameters
    ----------
    unit : str
        One of ``s``, ``ms``, ``us`` (``µs``), ``ns`` (case-insensitive).
    what : str
        Context quoted in the error message.

    Returns
    -------
    float
        Divide values in ``unit`` by this to get seconds.
    """
    key = unit.strip().lower()
    if key not in TIME_UNITS_PER_S:
        raise InputError(f"{what}: unknown time unit {unit!r}; use one of s, ms, us, ns")
    return TIME_UNITS_PER_S[key]
