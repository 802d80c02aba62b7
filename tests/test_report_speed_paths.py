"""The report's fast paths give what the validating paths give (equivalence only, no timing).

* the plain-CSV reader (:func:`aeromag.workflows._report_read._read_csv_fast`, pyarrow straight into
  numpy) reads the same frame as the validating batch reader (``_read_batches``), and hands
  every file it is not sure of to it, so errors are worded the same;
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aeromag.errors import InputError
from aeromag.synthetic import simulate_calibration
from aeromag.workflows import _report_read as rep
from aeromag.workflows.compensate import compensate_file


@pytest.fixture(scope="module")
def out_csv(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("speed")
    df, _ = simulate_calibration(seed=3, n_boxes=1)
    df.to_csv(d / "cal.csv", index=False)
    compensate_file(d / "cal.csv", d / "out.csv")
    return d / "out.csv"


def test_fast_reader_equals_validating_reader(out_csv: Path) -> None:
    fast = rep._read_csv_fast(out_csv)
    slow = rep._read_batches(out_csv)
    assert fast is not None
    pd.testing.assert_frame_equal(fast, slow, check_exact=True)
    assert fast.attrs == slow.attrs
    assert fast["flux_x"].dtype == np.float32 and fast["mag_tl"].dtype == np.float64
    # _read_columns takes the fast path on a plain CSV
    pd.testing.assert_frame_equal(rep.read_columns(out_csv), slow, check_exact=True)


def _edit(src: Path, dst: Path, row: int, col: str, value: str) -> Path:
    lines = src.read_text().splitlines()
    head = lines[0].split(",")
    f = lines[row + 1].split(",")
    f[head.index(col)] = value
    lines[row + 1] = ",".join(f)
    dst.write_text("\n".join(lines) + "\n")
    return dst


@pytest.mark.parametrize("col,value", [("mag", "abc"), ("time", ""), ("mag_tl", "inf"),
                                       ("time", "1e300"), ("line", "1e20")])
def test_fast_reader_declines_what_it_cannot_vouch_for(out_csv: Path, tmp_path: Path,
                                                        col: str, value: str) -> None:
    bad = _edit(out_csv, tmp_path / "bad.csv", 1000, col, value)
    with pytest.raises(rep._NotPlain):
        rep._read_csv_fast(bad)
    # the validating reader decides, with its own words; _read_columns says the same
    try:
        slow = rep._read_batches(bad)
    except InputError as exc:
        with pytest.raises(InputError) as got:
            rep.read_columns(bad)
        assert str(got.value) == str(exc)
    else:
        pd.testing.assert_frame_equal(rep.read_columns(bad), slow, check_exact=True)


def test_fast_reader_declines_iso_times_and_trailing_delimiters(out_csv: Path,
                                                                 tmp_path: Path) -> None:
    df = pd.read_csv(out_csv, nrows=50)
    iso = tmp_path / "iso.csv"
    d2 = df.copy()
    d2["time"] = pd.to_datetime(d2["time"] + 1.7e9, unit="s").dt.strftime("%Y-%m-%dT%H:%M:%S.%f")
    d2.to_csv(iso, index=False)
    with pytest.raises(rep._NotPlain):
        rep._read_csv_fast(iso)
    pd.testing.assert_frame_equal(rep.read_columns(iso), rep._read_batches(iso),
                                  check_exact=True)
    trail = tmp_path / "trail.csv"
    trail.write_text("\n".join(ln + "," for ln in
                               df.to_csv(index=False).splitlines()) + "\n")
    with pytest.raises(rep._NotPlain):
        rep._read_csv_fast(trail)
    pd.testing.assert_frame_equal(rep.read_columns(trail), rep._read_batches(trail),
                                  check_exact=True)
