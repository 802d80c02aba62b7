"""Chunked application of a saved model equals the in-memory application."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from aeromag.compensation.config import CompensationConfig
from aeromag.io import write_csv
from aeromag.io.formats import write_table
from aeromag.workflows.chunked import _median_from_counts, apply_model_chunked, overlap_rows
from aeromag.workflows.compensate import calibrate_file, compensate_file

from .conftest import hand_flight


@pytest.fixture(scope="module")
def model_path(tmp_path_factory):
    d = tmp_path_factory.mktemp("m")
    df, _ = hand_flight(seed=5, n=6000)
    write_csv(df.drop(columns=["truth_mag_tl", "truth_clean"]), d / "cal.csv")
    calibrate_file(d / "cal.csv", d / "model.json", CompensationConfig())
    return d / "model.json"


def _long_log(with_line: bool) -> pd.DataFrame:
    df, _ = hand_flight(seed=7, n=24000)
    df = df.drop(columns=["truth_mag_tl", "truth_clean"])
    df.loc[5000:5003, "mag"] = np.nan          # a short gap: interpolated
    df.loc[9000:9100, "flux_x"] = np.nan       # a long gap: splits a stretch
    df = df.drop(index=range(15000, 15030)).reset_index(drop=True)  # a time gap
    if not with_line:
        df = df.drop(columns=["line"])
    return df


def _compare(a_csv, b_csv):
    a = pd.read_csv(a_csv)
    b = pd.read_csv(b_csv)
    assert list(a.columns) == list(b.columns) and len(a) == len(b)
    for c in a.columns:
        if pd.api.types.is_numeric_dtype(a[c]) and not pd.api.types.is_bool_dtype(a[c]):
            np.testing.assert_allclose(b[c].to_numpy(float), a[c].to_numpy(float),
                                       rtol=1e-12, atol=1e-9, equal_nan=True, err_msg=c)
        else:
            assert a[c].tolist() == b[c].tolist(), c


@pytest.mark.parametrize("with_line", [True, False])
@pytest.mark.parametrize("ext", ["csv", "parquet"])
def test_chunked_equals_in_memory(tmp_path, model_path, with_line, ext):
    df = _long_log(with_line)
    src = tmp_path / f"survey.{ext}"
    write_table(df, src)
    cfg = CompensationConfig()
    ref = compensate_file(src, tmp_path / "mem.csv", cfg, model=model_path)
    rep = apply_model_chunked(src, tmp_path / "chunk.csv", model_path, cfg, chunk_rows=2500)
    assert rep.n_rows == len(df) and len(df) > 5 * 2500 + 2 * rep.chunked.overlap_rows
    _compare(tmp_path / "mem.csv", tmp_path / "chunk.csv")
    a = json.loads((tmp_path / "mem.json").read_text())
    b = json.loads((tmp_path / "chunk.json").read_text())
    assert a["sampling_rate_hz"] == b["sampling_rate_hz"]
    for k, v in a["metrics"].items():
        if isinstance(v, str):
            assert b["metrics"][k] == v, k
        else:
            assert b["metrics"][k] == pytest.approx(v, rel=1e-9), k
    assert [(s["id"], s["n"]) for s in a["segments"]] == [(s["id"], s["n"]) for s in b["segments"]]
    for sa, sb in zip(a["segments"], b["segments"], strict=True):
        assert sb["residual_std"] == pytest.approx(sa["residual_std"], rel=1e-8, abs=1e-12)
    assert ref.report.terms == b["terms"]
    # The QC block too: noise levels from fourth differences across chunk edges, and the
    # per-segment residuals.
    qa, qb = a["qc"], b["qc"]
    assert set(qa) == set(qb) and qb["fom"] == qa["fom"] and qb["notes"] == qa["notes"]
    for k in ("improvement_ratio", "residual_std_nT", "std_before_nT", "n_samples"):
        assert qb[k] == pytest.approx(qa[k], rel=1e-9), k
        assert qb["all_data"][k] == pytest.approx(qa["all_data"][k], rel=1e-9), k
    for k, v in qa["noise"].items():
        assert qb["noise"][k] == pytest.approx(v, rel=1e-9), k
    assert qa["residual_std_by_segment_nT"].keys() == qb["residual_std_by_segment_nT"].keys()
    for k, v in qa["residual_std_by_segment_nT"].items():
        assert qb["residual_std_by_segment_nT"][k] == pytest.approx(v, rel=1e-8, abs=1e-12)


def test_median_and_overlap():
    vals = np.array([0.1, 0.1, 0.2, 0.3, 0.1, 0.25])
    u, c = np.unique(vals, return_counts=True)
    assert _median_from_counts(dict(zip(u.tolist(), c.tolist(), strict=True))) == np.median(vals)
    assert _median_from_counts({0.1: 3, 0.2: 2}) == 0.1
    n10 = overlap_rows(10.0, CompensationConfig())
    n1k = overlap_rows(1000.0, CompensationConfig())
    assert 100 < n10 < n1k  # the context grows with the samples per filter time constant


def test_chunked_reads_trailing_delimiters_and_refuses_duplicate_names(tmp_path):
    from aeromag.errors import InputError
    from aeromag.workflows.compensate import calibrate_file

    df, _ = hand_flight(n=6000)
    df = df.drop(columns=["truth_mag_tl", "truth_clean"])
    src = tmp_path / "log.csv"
    df.to_csv(src, index=False)
    lines = src.read_text().splitlines()
    trail = tmp_path / "trail.csv"
    trail.write_text("\n".join([lines[0]] + [ln + "," for ln in lines[1:]]) + "\n")
    dup = tmp_path / "dup.csv"
    dup.write_text("\n".join([lines[0].replace("flux_z", "mag")] + lines[1:]) + "\n")
    calibrate_file(src, tmp_path / "m.json")
    apply_model_chunked(src, tmp_path / "a.csv", tmp_path / "m.json", chunk_rows=1000)
    apply_model_chunked(trail, tmp_path / "b.csv", tmp_path / "m.json", chunk_rows=1000)
    a = pd.read_csv(tmp_path / "a.csv")
    b = pd.read_csv(tmp_path / "b.csv")
    pd.testing.assert_frame_equal(a, b)
    with pytest.raises(InputError, match="appears twice"):
        apply_model_chunked(dup, tmp_path / "c.csv", tmp_path / "m.json", chunk_rows=1000)
    assert not (tmp_path / "c.csv").exists()


# --------------------------------------------------------------------------- issue 16
def _both(tmp_path, model_path, src, **kw):
    """Compensate ``src`` in memory and chunked; both outputs' bytes."""
    mem, chk = tmp_path / "mem.csv", tmp_path / "chk.csv"
    compensate_file(src, mem, CompensationConfig(), model=model_path, **kw)
    apply_model_chunked(src, chk, model_path, CompensationConfig(), chunk_rows=700, **kw)
    return mem.read_bytes(), chk.read_bytes()


@pytest.mark.parametrize("variant", ["bom", "blank_lines", "iso_time", "quoted_header",
                                     "trailing_delimiter", "duplicate_row", "integral_floats"])
def test_chunked_accepts_what_read_log_accepts_and_writes_the_same_bytes(tmp_path, model_path,
                                                                         variant):
    """Class: valid files rejected by --chunk-rows only (BOM, leading blank lines, ISO times,
    quoted headers), exact duplicates refused, and '0.0' written '0' by the chunked path."""
    df = _long_log(True).iloc[:3000].reset_index(drop=True)
    df["zero"] = 0.0
    df.loc[2500:, "zero"] = 0.25  # integral in the first chunks only
    src = tmp_path / "in.csv"
    write_csv(df, src)
    raw = src.read_bytes()
    if variant == "bom":
        raw = b"\xef\xbb\xbf" + raw
    elif variant == "blank_lines":
        raw = b"\n\n" + raw
    elif variant == "iso_time":
        t = pd.Timestamp("2024-05-01T08:00:00") + pd.to_timedelta(df["time"], unit="s")
        df2 = df.assign(time=t.dt.strftime("%Y-%m-%dT%H:%M:%S.%f"))
        df2.to_csv(src, index=False)
        raw = src.read_bytes()
    elif variant == "quoted_header":
        head, rest = raw.split(b"\n", 1)
        raw = b",".join(b'"%s"' % c for c in head.split(b",")) + b"\n" + rest
    elif variant == "trailing_delimiter":
        raw = raw.replace(b"\n", b",\n")
        raw = raw.replace(b",\n", b"\n", 1)  # the header has no trailing delimiter
    elif variant == "duplicate_row":
        lines = raw.split(b"\n")
        raw = b"\n".join([*lines[:900], lines[899], *lines[900:]])
    src.write_bytes(raw)
    mem, chk = _both(tmp_path, model_path, src)
    assert mem == chk
    if variant == "integral_floats":
        assert b",0.0," in chk


def test_chunked_parquet_datetime_time_and_corrupt_parquet(tmp_path, model_path):
    df = _long_log(True).iloc[:3000].reset_index(drop=True)
    df["time"] = pd.Timestamp("2024-05-01", tz="UTC") + pd.to_timedelta(df["time"], unit="s")
    src = tmp_path / "in.parquet"
    write_table(df, src)
    mem, chk = _both(tmp_path, model_path, src)
    assert mem == chk
    from aeromag.errors import InputError

    raw = src.read_bytes()
    for cut in (len(raw) // 2, len(raw) - 20):
        src.write_bytes(raw[:cut])
        with pytest.raises(InputError, match=r"in.parquet: cannot read as Parquet"):
            apply_model_chunked(src, tmp_path / "x.csv", model_path, chunk_rows=700)
        assert not (tmp_path / "x.csv").exists()


def test_chunked_refuses_what_read_log_refuses_naming_the_line(tmp_path, model_path):
    from aeromag.errors import InputError
    from aeromag.io import read_log

    df = _long_log(True).iloc[:3000].reset_index(drop=True)
    src = tmp_path / "in.csv"
    write_csv(df, src)
    lines = src.read_bytes().split(b"\n")
    cases = {
        "short": [*lines[:1500], b",".join(lines[1500].split(b",")[:4]), *lines[1501:]],
        "truncated": [*lines[:-2], lines[-2][:12]],
        "non_utf8": [*lines[:1200], lines[1200] + b"\xff", *lines[1201:]],
    }
    cols = lines[0].split(b",")
    j = cols.index(b"mag")
    cells = lines[2000].split(b",")
    cells[j] = b"abc"
    cases["text"] = [*lines[:2000], b",".join(cells), *lines[2001:]]
    for name, body in cases.items():
        src.write_bytes(b"\n".join(body))
        with pytest.raises(InputError) as want:
            read_log(src)
        with pytest.raises(InputError) as got:
            apply_model_chunked(src, tmp_path / "x.csv", model_path, chunk_rows=700)
        assert str(got.value) == str(want.value), name
        assert "line" in str(got.value)
        assert not (tmp_path / "x.csv").exists()
