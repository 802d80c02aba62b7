"""The Figure of Merit block as typed objects (the QC's ``fom``, :func:`aeromag.qc.fom_summary`).

* :class:`FomSummary` - the block: box FOM before/after (and truth), per box, per manoeuvre;
* :class:`FomBox` - one calibration box (an entry of ``boxes``);
* :class:`FomManeuver` - one (heading, manoeuvre) pair averaged over the complete boxes (an
  entry of ``per_maneuver``);
* :class:`FomTableRow` - one manoeuvre of :func:`aeromag.qc.fom_table` (an entry of ``table``).

A FOM exists only for the fields a manoeuvre table holds (``before``, ``after``, ``truth`` in
a simulation): their keys are written only for those, and a key written as ``null`` (a FOM of
an incomplete box, a field filtered to nothing) stays a ``null``.  As for
:class:`~aeromag.compensation.segments.SegmentRow`, ``None`` means absent and the optional
keys written as ``null`` are listed in ``nulls``; ``set`` keeps the two in step.
``to_dict()`` gives the block exactly as the files have always held it and ``from_dict()``
reads it back (``from_dict(d).to_dict() == d``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Self

from ..compensation.metrics import NullableBlock, split_fields

__all__ = ["FomBox", "FomManeuver", "FomSummary", "FomTableRow"]


class _Optional(NullableBlock):
    """Optional fields written when set: not None, or None listed in ``nulls``."""

    extra: dict[str, Any]
    #: Fields always written, None or not.
    ALWAYS: frozenset[str] = frozenset()

    def written(self, key: str) -> bool:
        """Whether ``key`` is a key of the JSON block.

        Parameters
        ----------
        key : str
            Attribute name.

        Returns
        -------
        bool
        """
        return key in self.ALWAYS or getattr(self, key) is not None or key in self.nulls

    def to_dict(self) -> dict[str, Any]:
        """The JSON entry: the fields in order when written (:meth:`written`), then ``extra``.

        Returns
        -------
        dict
        """
        return self._dict()

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> Self:
        """An entry read from a file; a key that is ``null`` there is listed in ``nulls``.

        Parameters
        ----------
        d : dict

        Returns
        -------
        instance of the class
        """
        return cls._read(d)

    def _dict(self, order: tuple[str, ...] | None = None) -> dict[str, Any]:
        names = order or tuple(f.name for f in dataclasses.fields(self)  # type: ignore[arg-type]
                               if f.name not in ("nulls", "extra"))
        d = {k: _out(getattr(self, k)) for k in names if self.written(k)}
        d.update(self.extra)
        return d

    @classmethod
    def _read(cls, d: dict[str, Any], **conv: Any) -> Any:
        kw, extra = split_fields(cls, d)
        for k, f in conv.items():
            if kw.get(k) is not None:
                kw[k] = f(kw[k])
        nulls = frozenset(k for k, v in kw.items() if v is None) - cls.ALWAYS
        return cls(**kw, nulls=nulls, extra=extra)


def _out(v: Any) -> Any:
    if isinstance(v, list):
        return [x.to_dict() if hasattr(x, "to_dict") else x for x in v]
    return v


@dataclass
class FomManeuver(_Optional):
    """Peak-to-peak of one (heading, manoeuvre) pair, averaged over the complete boxes.

    Attributes
    ----------
    heading : str
        ``N``, ``E``, ``S`` or ``W``.
    maneuver : str
        ``pitch``, ``roll`` or ``yaw``.
    ptp_before_nT, ptp_after_nT, ptp_truth_nT : float or None
        Mean peak-to-peak of each field [nT] (only the fields the table holds).
    nulls : frozenset of str
        Optional keys written as ``null``.
    extra : dict
        Keys this class does not know (written after the others).
    """

    heading: str = ""
    maneuver: str = ""
    ptp_before_nT: float | None = None
    ptp_after_nT: float | None = None
    ptp_truth_nT: float | None = None
    nulls: frozenset[str] = frozenset()
    extra: dict[str, Any] = field(default_factory=dict)

    ALWAYS = frozenset({"heading", "maneuver"})


@dataclass
class FomTableRow(_Optional):
    """One manoeuvre of the FOM table (:func:`aeromag.qc.fom_table`, the block's ``table``).

    Attributes
    ----------
    id : int
        Manoeuvre id.
    box : int
        Calibration box (visit number of the heading).
    heading_leg : int
        Cardinal heading, 0-3 (N, E, S, W).
    heading : str
        Its letter.
    maneuver : str
        ``pitch``, ``roll`` or ``yaw``.
    t_start, t_end : float
        Time span [s].
    ptp_before_nT, ptp_after_nT, ptp_truth_nT : float or None
        Peak-to-peak of each band-passed field within the manoeuvre [nT].
    kept : bool or None
        Every sample of the manoeuvre lies in a kept segment.
    nulls : frozenset of str
        Optional keys written as ``null``.
    extra : dict
        Columns this class does not know (written after the others).
    """

    id: int = -1
    box: int = -1
    heading_leg: int = -1
    heading: str = ""
    maneuver: str = ""
    t_start: float | None = None
    t_end: float | None = None
    ptp_before_nT: float | None = None
    ptp_after_nT: float | None = None
    ptp_truth_nT: float | None = None
    kept: bool | None = None
    nulls: frozenset[str] = frozenset()
    extra: dict[str, Any] = field(default_factory=dict)

    ALWAYS = frozenset({"id", "box", "heading_leg", "heading", "maneuver"})


@dataclass
class FomBox(_Optional):
    """One calibration box of the FOM (an entry of the block's ``boxes``).

    Attributes
    ----------
    box : int
        Box number.
    n_maneuvers : int
        Manoeuvres found in it.
    complete : bool
        All 12 (heading, manoeuvre) pairs found.
    missing : list of str
        The pairs not found (``"W pitch"``...).
    fom_before_nT, fom_after_nT, fom_truth_nT : float or None
        Sum of the 12 peak-to-peak values of each field [nT] (None for an incomplete box).
    n_maneuvers_kept : int or None
        Manoeuvres wholly in kept segments (when the log has ``segment_kept``).
    dropped : list of str or None
        The pairs in dropped segments.
    fom_kept_before_nT, fom_kept_after_nT, fom_kept_truth_nT : float or None
        The FOM when all 12 manoeuvres are kept, None otherwise [nT].
    kept_reason : str or None
        Why the box has no kept FOM.
    nulls : frozenset of str
        Optional keys written as ``null``.
    extra : dict
        Keys this class does not know (written after the others).
    """

    box: int = -1
    n_maneuvers: int = 0
    complete: bool = False
    missing: list[str] = field(default_factory=list)
    fom_before_nT: float | None = None
    fom_after_nT: float | None = None
    fom_truth_nT: float | None = None
    n_maneuvers_kept: int | None = None
    dropped: list[str] | None = None
    fom_kept_before_nT: float | None = None
    fom_kept_after_nT: float | None = None
    fom_kept_truth_nT: float | None = None
    kept_reason: str | None = None
    nulls: frozenset[str] = frozenset()
    extra: dict[str, Any] = field(default_factory=dict)

    ALWAYS = frozenset({"box", "n_maneuvers", "complete", "missing"})


#: Keys of the block of a flight without manoeuvres (:func:`aeromag.qc.fom.fom_not_applicable`),
#: in its order.
_NOT_APPLICABLE_ORDER = ("applicable", "reason", "fom_before_nT", "fom_after_nT",
                         "fom_reduction", "boxes", "complete_boxes", "n_maneuvers",
                         "per_maneuver")


@dataclass
class FomSummary(_Optional):
    """The Figure of Merit block (:func:`aeromag.qc.fom.fom_summary`), or why there is none.

    Two kinds, which write their keys in different orders (the order the files have always
    had): measured from a manoeuvre table (``from_table``) or the block of a flight without
    manoeuvres (:func:`aeromag.qc.fom.fom_not_applicable`).  ``fields`` is a mapping (one
    entry per field of the table).

    Attributes
    ----------
    applicable : bool
        A complete box exists.
    reason : str or None
        Why there is no FOM (None when there is one).
    boxes : list of FomBox
        Per box.
    complete_boxes : list of int
        The complete boxes.
    n_maneuvers : int
        Manoeuvres in the table.
    fields : dict of str to str or None
        The field each ``ptp_*_nT`` is of (``ptp_after_nT`` -> ``"mag - mag_tl"``...).
    definition : str or None
        The FOM in words.
    fom_before_nT, fom_after_nT, fom_truth_nT : float or None
        Mean box FOM over the complete boxes [nT] (None without one).
    kept_applicable : bool or None
        A complete box has all its manoeuvres in kept segments.
    kept_boxes : list of int or None
        Those boxes.
    fom_kept_before_nT, fom_kept_after_nT, fom_kept_truth_nT : float or None
        Mean FOM over them [nT].
    kept_reason : str or None
        The boxes left out of the kept FOM, and why.
    kept_definition : str or None
        The kept FOM in words.
    n_maneuvers_kept : int or None
        Manoeuvres wholly in kept segments.
    fom_reduction : float or None
        ``fom_before_nT / fom_after_nT`` [-].
    per_maneuver : list of FomManeuver
        Mean peak-to-peak per (heading, manoeuvre) over the complete boxes.
    table : list of FomTableRow or None
        Every manoeuvre (the QC adds it).
    from_table : bool
        Measured from a manoeuvre table (False: the not-applicable block); not a key.
    nulls : frozenset of str
        Optional keys written as ``null``.
    extra : dict
        Keys this class does not know (written after the others).
    """

    applicable: bool = False
    reason: str | None = None
    boxes: list[FomBox] = field(default_factory=list)
    complete_boxes: list[int] = field(default_factory=list)
    n_maneuvers: int = 0
    fields: dict[str, str] | None = None
    definition: str | None = None
    fom_before_nT: float | None = None
    fom_after_nT: float | None = None
    fom_truth_nT: float | None = None
    kept_applicable: bool | None = None
    kept_boxes: list[int] | None = None
    fom_kept_before_nT: float | None = None
    fom_kept_after_nT: float | None = None
    fom_kept_truth_nT: float | None = None
    kept_reason: str | None = None
    kept_definition: str | None = None
    n_maneuvers_kept: int | None = None
    fom_reduction: float | None = None
    per_maneuver: list[FomManeuver] = field(default_factory=list)
    table: list[FomTableRow] | None = None
    from_table: bool = True
    nulls: frozenset[str] = frozenset()
    extra: dict[str, Any] = field(default_factory=dict)

    ALWAYS = frozenset({"applicable", "reason", "boxes", "complete_boxes", "n_maneuvers",
                        "fom_reduction", "per_maneuver"})

    def to_dict(self) -> dict[str, Any]:
        """The JSON block, in its kind's order.

        Returns
        -------
        dict
        """
        names = tuple(f.name for f in dataclasses.fields(self)
                      if f.name not in ("from_table", "nulls", "extra"))
        if self.from_table:
            return self._dict(names)
        d = {k: _out(getattr(self, k)) for k in _NOT_APPLICABLE_ORDER}
        d.update(self._dict(tuple(k for k in names if k not in _NOT_APPLICABLE_ORDER)))
        return d

    def written(self, key: str) -> bool:
        """Whether ``key`` is a key of the JSON block.

        Parameters
        ----------
        key : str
            Attribute name.

        Returns
        -------
        bool
        """
        if not self.from_table and key in _NOT_APPLICABLE_ORDER:
            return True
        return super().written(key)

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> FomSummary | None:
        """A block read from a file (None for none).

        The not-applicable block is the one whose keys start ``applicable``, ``reason``,
        ``fom_before_nT``.

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        FomSummary or None
        """
        if not d:
            return None
        out = cls._read(
            d, boxes=lambda v: [FomBox.from_dict(e) for e in v],
            per_maneuver=lambda v: [FomManeuver.from_dict(e) for e in v],
            table=lambda v: [FomTableRow.from_dict(e) for e in v])
        out.from_table = list(d)[:3] != list(_NOT_APPLICABLE_ORDER[:3])
        if not out.from_table:
            out.nulls = out.nulls - set(_NOT_APPLICABLE_ORDER)
        return out
