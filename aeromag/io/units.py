"""Magnetic field units and their factors to nT: the one table the column maps and files use."""

from __future__ import annotations

from ..conventions import FLUX_COLUMNS
from ..errors import InputError

__all__ = ["FIELD_UNITS_TO_NT", "UNIT_GROUPS", "unit_factor"]

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

#: Unit groups: a key of ``units`` may name a group or a single column.
UNIT_GROUPS: dict[str, tuple[str, ...]] = {
    "flux": FLUX_COLUMNS,
    "mag": ("mag",),
}


def unit_factor(unit: str, *, what: str = "--units") -> float:
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
