"""The options a report records (its ``config`` block): :class:`ConfigRecord`."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields
from typing import Any

from .config import FIT_ONLY, CompensationConfig, config_dict

__all__ = ["ConfigRecord"]


@dataclass
class ConfigRecord:
    """The options a report records (its ``config`` block), as read or written.

    One attribute per :class:`CompensationConfig` keyword, of the same name and meaning
    (``band_hz`` and ``extras`` as lists); None for a keyword the block does not hold.  A
    fit records every keyword (``reference``, ``extras``, ``estimator`` only when set); an
    applied model leaves out the fit-only ones (:data:`FIT_ONLY`).  Unlike a
    :class:`CompensationConfig` it checks nothing: it is what a file says
    (:meth:`to_config` makes a configuration of it).

    Attributes
    ----------
    band_hz ... estimator
        :class:`CompensationConfig`'s keywords [their units].
    nulls : frozenset of str
        Keywords the block holds although their value is None (``null``: ``lowpass_hz``,
        ``fom``, ``max_gap_s`` left to their defaults...).
    extra : dict
        Keys this class does not know (written after the others).
    """

    band_hz: list[float] | None = None
    terms: str | None = None
    segment_seconds: float | None = None
    screen: bool | None = None
    filter_output: bool | None = None
    lowpass_hz: float | None = None
    order: int | None = None
    ridge: float | None = None
    shrink: float | None = None
    pca_variance: float | None = None
    screen_quantile: float | None = None
    max_iter: int | None = None
    min_segments: int | None = None
    min_excess: float | None = None
    min_excess_nT: float | None = None
    noise_factor: float | None = None
    min_segment_seconds: float | None = None
    max_gap_s: float | None = None
    max_interp_s: float | None = None
    trim_s: float | None = None
    fom: bool | None = None
    max_condition: float | None = None
    max_interference: float | None = None
    gross_excess: float | None = None
    inlier_excess: float | None = None
    inlier_own_excess: float | None = None
    decimate: bool | None = None
    mag_from_fluxgate: bool | None = None
    reference: str | None = None
    extras: list[str] | None = None
    estimator: str | None = None
    nulls: frozenset[str] = frozenset()
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)

    @classmethod
    def from_config(cls, cfg: CompensationConfig, *, applied: bool = False) -> ConfigRecord:
        """The record of a run's configuration (:func:`config_dict`).

        Parameters
        ----------
        cfg : CompensationConfig
            The configuration.
        applied : bool
            A saved model was applied: the fit-only keywords (:data:`FIT_ONLY`) played no
            part and are left out (the model's terms are the report's ``terms``).

        Returns
        -------
        ConfigRecord
        """
        d = config_dict(cfg)
        if applied:
            d = {k: v for k, v in d.items() if k not in FIT_ONLY}
        return cls.from_dict(d)

    def options(self) -> dict[str, Any]:
        """The keywords the block holds, as :class:`CompensationConfig` keywords.

        Returns
        -------
        dict
            Keyword to value, in the block's order (``null`` ones included as None).
        """
        return {f.name: getattr(self, f.name) for f in fields(self)
                if f.name not in ("nulls", "extra")
                and (getattr(self, f.name) is not None or f.name in self.nulls)}

    def to_config(self, **defaults: Any) -> CompensationConfig:
        """A :class:`CompensationConfig` of the recorded keywords (defaults for the others).

        Parameters
        ----------
        **defaults
            Keywords used where the block holds none (e.g. the report's ``band_hz``).

        Returns
        -------
        CompensationConfig
        """
        kw = dict(defaults)
        kw.update(self.options())
        return CompensationConfig(**kw)

    def to_dict(self) -> dict[str, Any]:
        """The JSON ``config`` block: the keywords it holds, in :class:`CompensationConfig`'s order.

        Returns
        -------
        dict
        """
        d = self.options()
        for key in ("band_hz", "extras"):
            if d.get(key) is not None:
                d[key] = list(d[key])
        d.update(self.extra)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any] | None) -> ConfigRecord | None:
        """A ``config`` block read from a file (None for none).

        Parameters
        ----------
        d : dict or None

        Returns
        -------
        ConfigRecord or None
        """
        if d is None:
            return None
        names = {f.name for f in fields(cls)} - {"nulls", "extra"}
        kw = {k: v for k, v in d.items() if k in names}
        nulls = frozenset(k for k, v in kw.items() if v is None)
        return cls(**kw, nulls=nulls, extra={k: v for k, v in d.items() if k not in names})
