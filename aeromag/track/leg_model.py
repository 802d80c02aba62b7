"""The parameters of the leg assignment: :class:`LegModel`.

One level below its users (:mod:`aeromag.track.legs`, :mod:`aeromag.track.continuation`,
the assignment and the diagnosis), so that none imports another for its type.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from ..errors import InputError

__all__ = ["LegModel"]


@dataclass(frozen=True)
class LegModel:
    """Parameters of the leg-assignment model (see the module docstring).

    Attributes
    ----------
    tolerance_m : float
        Horizontal distance to a leg's line at which the evidence for the leg is nil, m.
    vertical_tolerance_m : float
        Vertical distance at which the evidence is nil, m.
    end_margin_m : float
        Scale of the progress penalty before the first and past the last waypoint, m.
    min_speed_m_s : float
        Speed along the leg at which the motion term is half-way, m/s.
    speed_softness_m_s : float
        Width of the motion term's speed sigmoid, m/s.
    direction_softness_m_s : float
        Width of the motion term's direction sigmoid, m/s.
    direction_ratio : float
        ``r``: the direction sigmoid compares the speed along the leg with ``r`` times the
        speed across it (half-way at ``atan(1 / r)``: 18 degrees from the leg for 3).
    velocity_window_s : float
        Time window of the velocity from positions, s (at least the two neighbours).
    bonus : float
        Evidence of a sample flown on the leg (log-likelihood ratio, nats).
    floor : float
        Lowest evidence of one sample, nats.
    switch_cost : float
        Cost of a change of state, nats.
    order_cost : float
        Extra cost of entering a leg out of mission order, nats.
    step_s : float
        Finest time step of the decoding, s (faster logs are decoded in blocks).
    horizontal_only : bool
        Leave out the vertical term.
    """

    tolerance_m: float = 10.0
    vertical_tolerance_m: float = 10.0
    end_margin_m: float = 0.5
    min_speed_m_s: float = 0.5
    speed_softness_m_s: float = 0.15
    direction_softness_m_s: float = 0.25
    direction_ratio: float = 4.0
    velocity_window_s: float = 1.0
    bonus: float = 4.0
    floor: float = -10.0
    switch_cost: float = 8.0
    order_cost: float = 40.0
    step_s: float = 0.1
    horizontal_only: bool = False

    def __post_init__(self) -> None:
        for name in ("tolerance_m", "vertical_tolerance_m", "end_margin_m", "speed_softness_m_s",
                     "direction_softness_m_s", "direction_ratio", "velocity_window_s", "bonus",
                     "switch_cost", "step_s"):
            v = getattr(self, name)
            if not np.isfinite(v) or v <= 0:
                raise InputError(f"leg model: {name} = {v!r} must be a positive number")
        if not np.isfinite(self.min_speed_m_s) or self.min_speed_m_s < 0:
            raise InputError(f"leg model: min_speed_m_s = {self.min_speed_m_s!r} must be >= 0")
        if not np.isfinite(self.order_cost) or self.order_cost < 0:
            raise InputError(f"leg model: order_cost = {self.order_cost!r} must be >= 0")
        if not np.isfinite(self.floor) or self.floor >= 0:
            raise InputError(f"leg model: floor = {self.floor!r} must be negative")

    def to_dict(self) -> dict[str, float | bool]:
        """JSON-ready parameters."""
        return asdict(self)
