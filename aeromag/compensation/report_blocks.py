"""The smaller blocks of the compensation report, typed (re-exported by :mod:`.report_types`).

``segmentation`` (:class:`Segmentation`), ``calibration_box`` / ``self_calibration``
(:class:`CalibrationCheck`), ``chunked`` (:class:`ChunkSettings`), ``extended``
(:class:`ExtendedSummary` with its :class:`HeldOut`) and ``aeromag report``'s
``headline_check`` (:class:`HeadlineCheck` with its :class:`HeadlineDifference` rows and
:class:`MagCompCheck`).  Each has
``to_dict()`` (the JSON block the files have always held, keys in their order) and
``from_dict()`` (a block read back; keys it does not know in ``extra``).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from .metrics import FlatBlock, split_fields

__all__ = ["CalibrationCheck", "ChunkSettings", "ExtendedSummary", "HeadlineCheck",
           "HeadlineDifference", "HeldOut", "MagCompCheck", "Segmentation"]

_known = split_fields


def _set_dict(obj: Any, always: frozenset[str] = frozenset()) -> dict[str, Any]:
    """A JSON block from a dataclass: its fields but the None ones (bar ``always``), ``extra``.

    A field in ``always`` or in the object's ``nulls`` is written as ``null`` when None.
    """
    keep = always | getattr(obj, "nulls", frozenset())
    d: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        if f.name in ("extra", "nulls"):
            continue
        v = getattr(obj, f.name)
        if v is not None or f.name in keep:
            d[f.name] = v.to_dict() if hasattr(v, "to_dict") else v
    d.update(obj.extra)
    return d


def _set_from_dict(cls: type, d: dict[str, Any], always: frozenset[str] = frozenset(),
                   **convert: Any) -> Any:
    """:func:`_set_dict` read back; ``convert`` maps a field to the function that reads it."""
    kw, extra = _known(cls, d)
    for name, read in convert.items():
        if kw.get(name) is not None:
            kw[name] = read(kw[name])
    if any(f.name == "nulls" for f in dataclasses.fields(cls)):
        kw["nulls"] = frozenset(k for k, v in kw.items() if v is None) - always
    return cls(**kw, extra=extra)


@dataclass
class Segmentation:
    """How a calibration log without a ``line`` column was segmented (``segmentation``).

    Attributes
    ----------
    method : str
        ``detected maneuvers``, ``detected heading legs`` or ``time windows``.
    detector : str or None
        The detector's method (:func:`aeromag.qc.detect_maneuvers`), when one found them.
    n_segments : int or None
        Segments it found.
    segment_seconds : float or None
        Window length of the time windows [s].
    reason : str or None
        Why time windows were used.
    extra : dict
        Keys this class does not know (written after the others).
    """

    method: str = ""
    detector: str | None = None
    n_segments: int | None = None
    segment_seconds: float | None = None
    reason: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (the keys that are set).

        Returns
        -------
        dict
        """
        return _set_dict(self, frozenset({"method"}))

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> Segmentation | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        Segmentation or None
        """
        return None if d is None else _set_from_dict(cls, d)


@dataclass
class CalibrationCheck:
    """Whether a log holds a calibration box (``calibration_box``, ``self_calibration``).

    ``calibrate`` records it as ``calibration_box``; a log fitted on itself
    (``compensate`` without a model) as ``self_calibration``, with ``metrics`` saying that
    its figures are in-sample.

    Attributes
    ----------
    calibration_box : bool
        At least four heading legs with pitch, roll and yaw maneuvers.
    headings : list of str
        Heading legs found (``N``, ``E``...).
    maneuvers : list of str
        Maneuver kinds found.
    metrics : str or None
        What the metrics of a log fitted on itself mean (``self_calibration`` only).
    extra : dict
        Keys this class does not know (written after the others).
    """

    calibration_box: bool = False
    headings: list[str] = field(default_factory=list)
    maneuvers: list[str] = field(default_factory=list)
    metrics: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (``metrics`` first when set).

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {} if self.metrics is None else {"metrics": self.metrics}
        d.update(calibration_box=self.calibration_box, headings=list(self.headings),
                 maneuvers=list(self.maneuvers))
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> CalibrationCheck | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        CalibrationCheck or None
        """
        if d is None:
            return None
        kw, extra = _known(cls, d)
        kw["calibration_box"] = bool(kw.get("calibration_box", False))
        kw["headings"] = list(kw.get("headings") or [])
        kw["maneuvers"] = list(kw.get("maneuvers") or [])
        return cls(**kw, extra=extra)

@dataclass
class ChunkSettings(FlatBlock):
    """The chunks of a chunked run (``chunked``).

    Attributes
    ----------
    chunk_rows : int
        Rows written per chunk.
    overlap_rows : int
        Rows of context read on each side of a chunk.
    extra : dict
        Keys this class does not know (written after the others).
    """

    chunk_rows: int = 0
    overlap_rows: int = 0
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class HeldOut(FlatBlock):
    """The extended fit's held-out errors (``extended.held_out``).

    Attributes
    ----------
    method : str
        How they were measured, in words.
    residual_std_nT : float
        Held-out residual std of the fit with every regressor [nT].
    tl_only_residual_std_nT : float
        The same with the TL terms only [nT].
    tl_only_param : float
        The regularisation of the TL-only fit.
    contributions : list of dict
        Per extra: ``name``, ``held_out_std_without_nT``, ``increase_nT`` [nT],
        ``increase_pct`` [%].
    extra : dict
        Keys this class does not know (written after the others).
    """

    method: str | None = None
    residual_std_nT: float | None = None
    tl_only_residual_std_nT: float | None = None
    tl_only_param: float | None = None
    contributions: list[dict[str, Any]] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class ExtendedSummary:
    """The extended fit's block (``extended``; :meth:`ExtendedModel.summary`).

    Attributes
    ----------
    reference : str or None
        Reference column the model was fitted against (None: band-passed self-fit).
    rows_left_out : int or None
        Rows without a value in an extra or the reference.
    dropped_extras : list of str or None
        Extras dropped (constant or empty).
    mlp_training : dict or None
        How the network was trained and judged (``kept``, ``linear_std_nT``,
        ``mlp_std_nT`` [nT], ``epochs``, ``split``, ``hidden``, ``seed``).
    held_out : HeldOut or None
        Held-out errors.
    n_fit_samples : int or None
        Samples of the fit.
    estimator : str or None
        ``ridge``, ``pls`` or ``mlp``.
    param : float or None
        The regularisation chosen (relative ridge, or PLS components).
    intercept_nT : float or None
        Constant of the model [nT].
    extras : list of dict
        Per extra: ``name``, ``coef_nT_per_unit`` [nT per unit], ``center``, ``scale``
        (units of the column).
    mlp : dict or None
        The network's weights, when kept.
    fitted : bool
        The block of a fit (``reference`` written first); False for a saved model's block,
        which writes the fit's record before the model's keys.
    extra : dict
        Keys this class does not know (written with the fit's record).
    """

    reference: str | None = None
    rows_left_out: int | None = None
    dropped_extras: list[str] | None = None
    mlp_training: dict[str, Any] | None = None
    held_out: HeldOut | None = None
    n_fit_samples: int | None = None
    estimator: str | None = None
    param: float | None = None
    intercept_nT: float | None = None
    extras: list[dict[str, Any]] = field(default_factory=list)
    mlp: dict[str, Any] | None = None
    fitted: bool = True
    extra: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The JSON block, in the order of its origin (a fit's, or a saved model's).

        Returns
        -------
        dict
        """
        d: dict[str, Any] = {"reference": self.reference} if self.fitted else {}
        for key in ("rows_left_out", "dropped_extras", "mlp_training", "held_out",
                    "n_fit_samples"):
            v = getattr(self, key)
            if v is not None:
                d[key] = v.to_dict() if hasattr(v, "to_dict") else v
        d.update(self.extra)
        d.update(reference=self.reference, estimator=self.estimator, param=self.param,
                 intercept_nT=self.intercept_nT, extras=list(self.extras), mlp=self.mlp)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> ExtendedSummary | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        ExtendedSummary or None
        """
        if d is None:
            return None
        kw, extra = _known(cls, d)
        kw.pop("fitted", None)
        kw["held_out"] = HeldOut.from_dict(kw.get("held_out"))
        kw["extras"] = list(kw.get("extras") or [])
        return cls(**kw, fitted=next(iter(d), None) == "reference", extra=extra)


@dataclass
class HeadlineDifference(FlatBlock):
    """One figure of the headline check (an entry of ``headline_check.differences``).

    Attributes
    ----------
    computed, recorded : float or int or None
        The figure computed from the log and the one the report recorded.
    relative : float
        ``|computed - recorded| / |recorded|`` [-] (inf when one is missing).
    extra : dict
        Keys this class does not know (written after the others).
    """

    computed: Any = None
    recorded: Any = None
    relative: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)


@dataclass
class MagCompCheck:
    """``aeromag report``'s check of a log's ``mag_comp`` (``headline_check.mag_comp``).

    Attributes
    ----------
    compared : int
        Rows compared.
    max_abs_difference_nT : float or None
        Largest difference [nT].
    tolerance_nT : float
        Largest difference allowed [nT].
    first_row : int or None
        0-based data row of the first difference beyond the tolerance.
    filtered : bool
        Whether the expected ``mag_comp`` was low-passed.
    filter_recorded : bool
        Whether the report records the filter setting (an online report does not).
    warning : str or None
        The one-line warning.
    note : str or None
        Why the low-passed field was not compared.
    extra : dict
        Keys this class does not know (written after the others).
    """

    compared: int = 0
    max_abs_difference_nT: float | None = None
    tolerance_nT: float | None = None
    first_row: int | None = None
    filtered: bool | None = None
    filter_recorded: bool | None = None
    warning: str | None = None
    note: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    _ALWAYS = frozenset({"compared", "max_abs_difference_nT", "tolerance_nT", "first_row",
                         "filtered", "filter_recorded", "warning"})

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (``note`` only when set).

        Returns
        -------
        dict
        """
        return _set_dict(self, self._ALWAYS)

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> MagCompCheck | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        MagCompCheck or None
        """
        return None if d is None else _set_from_dict(cls, d)


@dataclass
class HeadlineCheck:
    """``aeromag report``'s comparison of the recomputed headline with the recorded one.

    The report's and ``qc.json``'s ``headline_check``
    (:func:`aeromag.workflows.report_check.compare_headline`).

    Attributes
    ----------
    compared : bool
        Whether the recorded metrics could be compared.
    agree : bool or None
        Whether they agree within the tolerance (None when not compared).
    relative_tolerance : float
        Tolerance of the figures [-].
    counts : str
        ``equal``: sample counts compare exactly.
    recorded_in : str
        The report file.
    warning : str or None
        The one-line warning of a disagreement.
    definition : str
        What is compared, in words.
    note : str or None
        Why nothing was compared.
    max_relative_difference : float or None
        The largest relative difference [-].
    differences : dict of str to HeadlineDifference or None
        Per figure (its keys are the figures' names).
    mag_comp : MagCompCheck or None
        The check of the log's ``mag_comp``.
    extra : dict
        Keys this class does not know (written after the others).
    """

    compared: bool = False
    agree: bool | None = None
    relative_tolerance: float | None = None
    counts: str | None = None
    recorded_in: str | None = None
    warning: str | None = None
    definition: str | None = None
    note: str | None = None
    max_relative_difference: float | None = None
    differences: dict[str, HeadlineDifference] | None = None
    mag_comp: MagCompCheck | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    _ALWAYS = frozenset({"compared", "agree", "relative_tolerance", "counts", "recorded_in",
                         "warning", "definition"})

    def to_dict(self) -> dict[str, Any]:
        """The JSON block (``note``, the differences and ``mag_comp`` only when set).

        Returns
        -------
        dict
        """
        d = _set_dict(self, self._ALWAYS)
        if self.differences is not None:
            d["differences"] = {k: v.to_dict() for k, v in self.differences.items()}
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> HeadlineCheck | None:
        """The block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        HeadlineCheck or None
        """
        if d is None:
            return None
        return _set_from_dict(cls, d, mag_comp=MagCompCheck.from_dict, differences=lambda v: {
            k: HeadlineDifference.from_dict(x) for k, x in v.items()})
