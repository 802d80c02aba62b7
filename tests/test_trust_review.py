"""Review 15: what the single-file commands say about a bad model, a missing mag, and why a
segment was dropped, checkable from the page.

1. A saved model that makes the data worse is a recorded warning in ``compensate`` (in
   memory and chunked) and an error under ``--strict``, the same words as ``batch``'s.
2. ``mag_comp`` is empty where ``mag`` is missing (in memory and chunked alike), and the rows
   are counted in the report and the summary.
3. A dropped segment's reason gives the median it is compared with (recomputable from the
   report); a too-short one its numbers; segments of an epoch log are named in UTC.
4. ``batch`` names a file once per warning and keeps its closing line whole.
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation import CompensationMetrics, SegmentRow

from .conftest import hand_flight

_m = CompensationMetrics.from_dict  # a metrics block as a report file holds it

runner = CliRunner()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("trust15")
    df, _ = hand_flight(seed=5, n=6000)
    df = df.drop(columns=["truth_mag_tl", "truth_clean"])
    df.to_csv(d / "cal.csv", index=False)
    r = runner.invoke(app, ["calibrate", str(d / "cal.csv"), "-o", str(d / "model.json")])
    assert r.exit_code == 0, r.output
    rep = json.loads((d / "model.json").read_text())
    rep["coef"] = [-c for c in rep["coef"]]  # adds the interference twice instead of removing it
    (d / "neg.json").write_text(json.dumps(rep))
    gap = df.copy()
    gap.loc[100:104, "mag"] = np.nan
    gap.to_csv(d / "gap.csv", index=False)
    return d


def _warnings(path):
    return json.loads(path.with_suffix(".json").read_text()).get("warnings") or []


def test_a_model_that_makes_the_data_worse_is_a_warning_and_strict_fails(files, tmp_path):
    from aeromag.compensation import checks
    from aeromag.workflows import batch

    log, neg = str(files / "cal.csv"), str(files / "neg.json")
    out = tmp_path / "neg.csv"
    r = runner.invoke(app, ["compensate", log, "--model", neg, "-o", str(out)])
    assert r.exit_code == 0, r.output
    w = [x for x in _warnings(out) if "improvement ratio" in x]
    assert len(w) == 1 and "< 1" in w[0] and w[0].startswith(f"{log}: ")
    # Chunked: the same warning.
    outc = tmp_path / "negc.csv"
    r = runner.invoke(app, ["compensate", log, "--model", neg, "-o", str(outc),
                            "--chunk-rows", "1500"])
    assert r.exit_code == 0, r.output
    assert [x for x in _warnings(outc) if "improvement ratio" in x] == w
    # --strict: an error, no output.
    for extra in ([], ["--chunk-rows", "1500"]):
        o = tmp_path / f"strict{len(extra)}.csv"
        r = runner.invoke(app, ["compensate", log, "--model", neg, "-o", str(o), "--strict",
                                *extra])
        assert r.exit_code == 1, r.output
        assert "improvement ratio" in r.output and not o.exists()
    # One implementation: batch gives the very same words, once.
    assert batch.metric_warnings is checks.metric_warnings
    s = batch.run_batch([log], tmp_path / "b", model=neg, workers=1, progress=False)
    res = s.results[0]
    assert res.status == "warn"
    assert [x for x in res.warnings if "improvement ratio" in x] == w
    # A good model: no such warning.
    good = tmp_path / "good.csv"
    r = runner.invoke(app, ["compensate", log, "--model", str(files / "model.json"), "-o",
                            str(good), "--strict"])
    assert r.exit_code == 0, r.output


def test_metric_checks_name_the_file_and_the_advice():
    from aeromag.compensation.checks import metric_warnings

    assert metric_warnings(_m({"improvement_ratio": 3.0, "residual_std_nT": 0.2})) == []
    fitted = metric_warnings(_m({"improvement_ratio": 0.5, "residual_std_nT": 0.2}),
                             source="a.csv", fitted=True)
    applied = metric_warnings(_m({"improvement_ratio": 0.5, "residual_std_nT": 0.2}),
                              source="a.csv")
    assert fitted[0].startswith("a.csv: the fitted model") and "calibrate" in fitted[0]
    assert applied[0].startswith("a.csv: the model") and "aircraft" in applied[0]
    assert "--" not in " ".join(metric_warnings(_m({"improvement_ratio": 2,
                                                 "residual_std_nT": 500.0})))


def test_mag_comp_is_empty_where_mag_is_missing(files, tmp_path):
    gap = str(files / "gap.csv")
    outs = {}
    for name, extra in (("self", []), ("model", ["--model", str(files / "model.json")]),
                        ("chunked", ["--model", str(files / "model.json"),
                                     "--chunk-rows", "700"])):
        o = tmp_path / f"{name}.csv"
        r = runner.invoke(app, ["compensate", gap, "-o", str(o), *extra])
        assert r.exit_code == 0, r.output
        assert "5 rows without mag: mag_comp left empty" in r.output
        rep = json.loads(o.with_suffix(".json").read_text())
        assert rep["metrics"]["n_rows_without_mag"] == 5
        outs[name] = pd.read_csv(o)
        comp = outs[name]["mag_comp"]
        assert comp.isna().to_numpy().nonzero()[0].tolist() == [100, 101, 102, 103, 104]
        assert np.isfinite(outs[name]["mag_tl"]).all()  # the model of the fluxgate stays
    a, b = outs["model"]["mag_comp"], outs["chunked"]["mag_comp"]
    assert np.nanmax(np.abs(a - b)) < 1e-6 and (a.isna() == b.isna()).all()
    # No missing mag: counted as 0, said nothing.
    r = runner.invoke(app, ["compensate", str(files / "cal.csv"), "-o", str(tmp_path / "c.csv"),
                            "--model", str(files / "model.json")])
    assert "without mag" not in r.output
    rep = json.loads((tmp_path / "c.json").read_text())
    assert rep["metrics"]["n_rows_without_mag"] == 0


def test_drop_reasons_can_be_recomputed_from_the_report(tmp_path):
    df, _ = hand_flight(seed=11, n=6000)
    rng = np.random.default_rng(3)
    bad = df["line"] == 4
    tt = df.loc[bad, "time"].to_numpy()
    df.loc[bad, "mag"] += 4 * np.sin(2 * np.pi * 0.4 * tt) + rng.normal(0, 1.0, bad.sum())
    df.loc[3000:3020, "line"] = 99  # 21 samples: too short to fit
    df.drop(columns=["truth_mag_tl", "truth_clean"]).to_csv(tmp_path / "f.csv", index=False)
    r = runner.invoke(app, ["calibrate", str(tmp_path / "f.csv"), "-o",
                            str(tmp_path / "m.json")])
    assert r.exit_code == 0, r.output
    rep = json.loads((tmp_path / "m.json").read_text())
    segs = rep["segments"]
    ref = [e["pool_residual_nT"] for e in segs
           if e["kept"] and not e.get("readmitted") and "pool_residual_nT" in e]
    med = float(np.median(ref))
    screened = [e for e in segs if not e["kept"] and not e.get("too_short")]
    assert screened and any(e.get("line") == 4 for e in screened)
    for e in screened:
        assert e["pool_median_nT"] == pytest.approx(med, rel=1e-12)
        assert e["pool_residual_nT"] / med == pytest.approx(e["residual_excess"], rel=1e-9)
        assert f"pooled-fit residual {e['pool_residual_nT']:.3g} nT" in e["reason"]
        assert (f"= {e['residual_excess']:.3g}x the median pooled-fit residual of the kept"
                f" segments ({med:.3g} nT)") in e["reason"]
    short = next(e for e in segs if e.get("too_short"))
    assert short["reason"] == (
        f"too short to fit: {short['n_fit']} usable samples of its {short['n']} (band-passed,"
        f" filter edges trimmed), needs \u2265 {short['min_samples']}")
    assert short["n"] == 21 and short["min_samples"] > short["n_fit"]


def test_segments_of_an_epoch_log_are_named_in_utc():
    from aeromag.compensation.report import format_time, segment_name, time_span

    e = SegmentRow(4, kept=False, start_time=1700000119.0, end_time=1700000149.9)
    assert segment_name(e, lines=False) == "segment 4 (22:15:19–22:15:49 UTC)"
    assert format_time(1700000119.0) == "22:15:19"
    # Log time that is no epoch: as the log has it, in seconds (as the HTML tables).
    assert time_span(120.0, 185.31) == "120.0–185.3 s"
    assert format_time(120.04) == "120.0"


def test_batch_names_a_file_once_and_keeps_its_closing_line(files, tmp_path):
    out = tmp_path / ("a_rather_long_output_folder_name_" * 2)
    r = runner.invoke(app, ["batch", str(files / "cal.csv"), "--model", str(files / "neg.json"),
                            "-o", str(out), "--workers", "1", "--no-progress"])
    assert r.exit_code == 0, r.output
    lines = r.output.splitlines()
    warn = [ln for ln in lines if ln.startswith("warning: ")]
    assert warn and all(ln.count("cal.csv") == 1 for ln in warn), warn
    closing = [ln for ln in lines if "summary:" in ln]
    assert len(closing) == 1 and closing[0].endswith(f"summary: {out / 'batch_summary.csv'}")
