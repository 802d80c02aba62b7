"""The real vendor samples of ../shared/data/formats through the commands a user would try.

They are too short to fit, so the right answer is a one-line refusal that says why, never a
traceback; and the MagDrone R3's second fluxgate (B2x..B2z) is no misnamed scalar.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aeromag.compensation.config import CompensationConfig
from aeromag.compensation.prepare import total_field_from_fluxgate
from aeromag.errors import InputError

SAMPLES = Path(__file__).resolve().parents[1] / "data_samples" / "formats"  # ../shared copies


def _frame(**cols: float) -> pd.DataFrame:
    n = 50
    return pd.DataFrame({k: np.full(n, v) for k, v in cols.items()})


def test_second_fluxgate_components_are_not_a_misnamed_scalar() -> None:
    df = _frame(time=0.0, flux_x=20000.0, flux_y=1000.0, flux_z=45000.0,
                B2x=21000.0, B2y=14712.0, B2z=44000.0)
    assert total_field_from_fluxgate(df, CompensationConfig(), "m.csv") is True


def test_a_misnamed_scalar_is_still_refused() -> None:
    df = _frame(time=0.0, flux_x=20000.0, flux_y=1000.0, flux_z=45000.0, mag_1_uc=50123.0)
    with pytest.raises(InputError, match="mag_1_uc"):
        total_field_from_fluxgate(df, CompensationConfig(), "m.csv")


def test_a_negative_component_sized_column_is_no_scalar() -> None:
    df = _frame(time=0.0, flux_x=20000.0, flux_y=1000.0, flux_z=45000.0, other=-30000.0)
    assert total_field_from_fluxgate(df, CompensationConfig(), "m.csv") is True


@pytest.mark.parametrize("command", ["calibrate", "compensate"])
def test_magdrone_sample_gives_one_line_not_a_traceback(tmp_path: Path, command: str) -> None:
    out = tmp_path / ("m.json" if command == "calibrate" else "m.csv")
    res = subprocess.run([sys.executable, "-m", "aeromag", command,
                          str(SAMPLES / "magdrone_r3_sample.csv"), "-o", str(out)],
                         capture_output=True, text=True, timeout=300)
    assert "Traceback" not in res.stderr
    assert res.returncode == 1, res.stderr
    errors = [ln for ln in res.stderr.splitlines() if ln.startswith("error: ")]
    assert len(errors) == 1 and "magdrone_r3_sample.csv" in errors[0]
    assert "--col mag=B2" not in errors[0]  # a fluxgate component is never offered as `mag`
    assert not out.exists()
