"""The sub-blocks of the QC metrics as typed objects (``qc.json``, the report's ``qc``).

:class:`~aeromag.qc.quality.QCMetrics` holds these instead of dicts; every layer above reads
their attributes and JSON exists only where a file is written or read.  Each has
``to_dict()`` (the block exactly as the files have always held it: keys, order, values) and
``from_dict()`` (a block read back; ``from_dict(d).to_dict() == d``).  Keys a class does not
know are kept in its ``extra`` and written after the known ones, as in
:mod:`aeromag.compensation.report_types`.

* :class:`RmsSummary` - rms figures over a set of samples (the ``all_data`` block);
* :class:`PieceRms`, :class:`PerPieceRms` - the per-piece rms diagnostic (``per_piece_rms``);
* :class:`NoiseSummary` - band-limited and fourth-difference noise (``noise``);
* :class:`ManeuverSummary` - what the manoeuvre detection found (``maneuvers``);
* :class:`HeadlineCheck`, :class:`HeadlineDifference`, :class:`MagCompCheck` - ``aeromag
  report``'s check of the recorded headline (``headline_check``);
* :class:`QCSegmentRow` - one row of the report's per-segment table (``segments``).

The FOM block is in :mod:`aeromag.qc.fom_types`, the fit diagnostics in
:mod:`aeromag._core.fit_diagnostics`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..compensation.metrics import FlatBlock, block_dict, block_from_dict, split_fields

__all__ = ["ManeuverSummary",
           "NoiseSummary", "PerPieceRms", "PieceRms", "QCSegmentRow", "RmsSummary"]


@dataclass
class RmsSummary(FlatBlock):
    """Rms of the band-passed fields over a set of samples (the QC's ``all_data`` block).

    Attributes
    ----------
    improvement_ratio : float or None
        ``std_before_nT / residual_std_nT`` [-] (None without a residual).
    residual_std_nT : float or None
        Rms (or std) of band-passed ``mag - mag_tl`` [nT] (None without samples).
    std_before_nT : float or None
        Rms (or std) of band-passed ``mag`` [nT] (None without samples).
    n_samples : int
        Samples used.
    extra : dict
        Keys this class does not know (written after the others).
    """

    improvement_ratio: float | None = None
    residual_std_nT: float | None = None
    std_before_nT: float | None = None
    n_samples: int = 0
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class PieceRms(FlatBlock):
    """The per-piece rms figures over one set of pieces (``per_piece_rms.kept`` / ``.all``).

    Attributes
    ----------
    per_piece_rms_ratio : float or None
        Rms of band-passed ``mag`` over that of ``mag - mag_tl`` [-].
    per_piece_rms_after_nT, per_piece_rms_before_nT : float or None
        Rms of band-passed ``mag - mag_tl`` and of ``mag``, each piece filtered alone [nT].
    n_samples : int
        Samples used.
    extra : dict
        Keys this class does not know (written after the others).
    """

    per_piece_rms_ratio: float | None = None
    per_piece_rms_after_nT: float | None = None
    per_piece_rms_before_nT: float | None = None
    n_samples: int = 0
    extra: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, rms: RmsSummary) -> PieceRms:
        """The per-piece figures of an :func:`aeromag.qc.residuals.rms_summary`.

        Parameters
        ----------
        rms : RmsSummary
            Rms over the pieces (:attr:`aeromag.qc.residuals.PieceResiduals.kept` or ``all``).

        Returns
        -------
        PieceRms
        """
        return cls(rms.improvement_ratio, rms.residual_std_nT, rms.std_before_nT,
                   rms.n_samples)


@dataclass
class PerPieceRms:
    """The per-piece rms diagnostic beside the headline (the QC's ``per_piece_rms`` block).

    Attributes
    ----------
    definition : str
        What the figures are (:func:`aeromag.qc.quality.residual_definition`).
    kept, all : PieceRms
        Over the kept segments and over every piece.
    extra : dict
        Keys this class does not know (written after the others).
    """

    definition: str
    kept: PieceRms
    all: PieceRms
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block.

        Returns
        -------
        dict
        """
        d = {"definition": self.definition, "kept": self.kept.to_dict(),
             "all": self.all.to_dict()}
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> PerPieceRms | None:
        """A block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        PerPieceRms or None
        """
        if not d:
            return None
        kw, extra = split_fields(cls, d)
        return cls(kw.get("definition", ""), PieceRms.from_dict(kw.get("kept")) or PieceRms(),
                   PieceRms.from_dict(kw.get("all")) or PieceRms(), extra=extra)


@dataclass
class NoiseSummary:
    """Noise before and after the compensation (the QC's ``noise`` block).

    Attributes
    ----------
    band_hz : list of float
        The fitting band [Hz].
    band_std_before_nT, band_std_after_nT : float or None
        Band-passed std of ``mag`` and of ``mag - mag_tl`` over all segments [nT].
    fourth_difference_before_nT, fourth_difference_after_nT : float or None
        Fourth-difference noise estimate of ``mag`` and of ``mag - mag_tl`` [nT].
    extra : dict
        Keys this class does not know (written after the others).
    """

    band_hz: list[float] = field(default_factory=list)
    band_std_before_nT: float | None = None
    band_std_after_nT: float | None = None
    fourth_difference_before_nT: float | None = None
    fourth_difference_after_nT: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block.

        Returns
        -------
        dict
        """
        d = block_dict(self)
        d["band_hz"] = list(self.band_hz)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> NoiseSummary | None:
        """A block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        NoiseSummary or None
        """
        return block_from_dict(cls, d)


@dataclass
class ManeuverSummary(FlatBlock):
    """What the manoeuvre detection found (the QC's ``maneuvers`` block).

    Attributes
    ----------
    method : str
        ``"attitude"``, ``"fluxgate"`` or ``"column:<name>"``.
    n_legs, n_maneuvers : int
        Heading legs and manoeuvres found.
    complete_boxes : list of int
        Boxes with all 12 (heading, manoeuvre) pairs.
    heading_offset_deg : float
        Common offset of the flown headings from the cardinals [deg].
    notes : list of str
        What the detection noticed.
    extra : dict
        Keys this class does not know (written after the others).
    """

    method: str = ""
    n_legs: int = 0
    n_maneuvers: int = 0
    complete_boxes: list[int] = field(default_factory=list)
    heading_offset_deg: float = 0.0
    notes: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class QCSegmentRow:
    """One row of the report's per-segment table (an entry of the QC's ``segments``).

    Built by :func:`aeromag.workflows.report.segment_rows`.

    Attributes
    ----------
    segment : int
        Segment id.
    line : int or float or None
        Its flight line.
    t_start, t_end : float
        Time span [s, the log's time].
    n : int
        Samples.
    kept : bool
        Whether the fit kept it.
    reason : str or None
        Why it was dropped (None when kept).
    residual_std_nT : float or None
        Band-passed ``mag - mag_tl`` of the segment, from the QC [nT].
    model_residual_std_nT : float or None
        The model file's residual of the segment [nT].
    extra : dict
        Keys this class does not know (written after the others).
    """

    segment: int
    line: int | float | None = None
    t_start: float | None = None
    t_end: float | None = None
    n: int = 0
    kept: bool = True
    reason: str | None = None
    residual_std_nT: float | None = None
    model_residual_std_nT: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON row.

        Returns
        -------
        dict
        """
        return block_dict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> QCSegmentRow:
        """A row read from a file.

        Parameters
        ----------
        d : dict

        Returns
        -------
        QCSegmentRow
        """
        kw, extra = split_fields(cls, d)
        kw.setdefault("segment", -1)
        return cls(**kw, extra=extra)
