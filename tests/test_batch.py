"""aeromag batch: per-file isolation, equality with single runs, Dask, skipping, CLI."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app
from aeromag.compensation import CompensationMetrics
from aeromag.compensation.config import CompensationConfig
from aeromag.errors import InputError
from aeromag.io import write_csv
from aeromag.workflows.batch import expand_inputs, run_batch
from aeromag.workflows.compensate import calibrate_file, compensate_file

from .conftest import hand_flight

_m = CompensationMetrics.from_dict  # a metrics block as a report file holds it


def _report(path: Path) -> dict:
    d = json.loads(path.read_text())
    d.pop("created", None)
    return d


@pytest.fixture(scope="module")
def logs(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("logs")
    for i in range(3):
        df, _ = hand_flight(seed=i, n=4000)
        write_csv(df.drop(columns=["truth_mag_tl", "truth_clean"]), d / f"flight{i}.csv")
    (d / "corrupt.csv").write_text("time,flux_x,flux_y,flux_z,mag\n0,1,2,3,4\n0.1,abc,2,3,4\n")
    (d / "empty.csv").write_text("")
    (d / "notes.md").write_text("not a log")
    return d


def _single(log: Path, out: Path, **kw) -> Path:
    """``aeromag compensate`` of one log (with its self-fit check, and its warnings recorded
    in OUT.json as inside the command's output set, as batch runs it)."""
    from aeromag.io.outputs import output_set

    target = out / f"{log.stem}_comp.csv"
    with output_set():
        compensate_file(log, target, CompensationConfig(), self_check=kw.get("model") is None,
                        **kw)
    return target


#: A self-fitted log without a calibration box (the hand-built flights have no attitude
#: columns) is a success with a warning: its level is not determined (issue 15).
SELF_FIT = "warn"


def test_folder_with_bad_files_local_pool(logs, tmp_path):
    summary = run_batch([logs], tmp_path / "out", workers=2, progress=False)
    status = {Path(r.input).name: r for r in summary.results}
    assert set(status) == {"flight0.csv", "flight1.csv", "flight2.csv", "corrupt.csv",
                           "empty.csv"}
    assert status["corrupt.csv"].status == "failed" and "'flux_x'" in status["corrupt.csv"].error
    assert "line 3" in status["corrupt.csv"].error
    assert status["empty.csv"].status == "failed" and "empty" in status["empty.csv"].error
    assert not summary.ok and len(summary.failed) == 2
    assert not (tmp_path / "out" / "corrupt_comp.csv").exists()
    single = tmp_path / "single"
    for i in range(3):
        assert status[f"flight{i}.csv"].status == SELF_FIT
        assert any("calibration box" in w for w in status[f"flight{i}.csv"].warnings)
        ref = _single(logs / f"flight{i}.csv", single)
        got = tmp_path / "out" / f"flight{i}_comp.csv"
        assert got.read_bytes() == ref.read_bytes()
        assert _report(got.with_suffix(".json")) == _report(ref.with_suffix(".json"))
    frame = pd.read_csv(summary.summary_csv)
    assert list(frame["status"]).count("failed") == 2
    js = json.loads(summary.summary_json.read_text())
    assert js["n_failed"] == 2 and js["n_warn"] == 3 and js["n_ok"] == 0


def test_skip_up_to_date_and_force(logs, tmp_path):
    files = [logs / "flight0.csv"]
    first = run_batch(files, tmp_path, workers=1, progress=False)
    assert first.results[0].status == SELF_FIT
    again = run_batch(files, tmp_path, workers=1, progress=False)
    assert again.results[0].status == "skipped"
    forced = run_batch(files, tmp_path, workers=1, progress=False, force=True)
    assert forced.results[0].status == SELF_FIT
    os.utime(files[0])  # the input changed after the outputs: redo
    assert run_batch(files, tmp_path, workers=1, progress=False).results[0].status == SELF_FIT


def test_glob_and_unmatched_inputs(logs, tmp_path):
    files, unmatched = expand_inputs([str(logs / "flight*.csv"), str(logs / "nope*.csv")])
    assert [f.name for f in files] == ["flight0.csv", "flight1.csv", "flight2.csv"]
    assert unmatched == [str(logs / "nope*.csv")]


def test_dask_local_cluster_identical(logs, tmp_path):
    distributed = pytest.importorskip("distributed")
    model = tmp_path / "model.json"
    calibrate_file(logs / "flight0.csv", model, CompensationConfig())
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        summary = run_batch([logs / "flight1.csv", logs / "flight2.csv", logs / "empty.csv"],
                            tmp_path / "dask", model=model, scheduler=cluster.scheduler_address,
                            progress=False)
    assert [r.status for r in summary.results] == ["ok", "ok", "failed"]
    local = run_batch([logs / "flight1.csv", logs / "flight2.csv"], tmp_path / "local",
                      model=model, workers=1, progress=False)
    assert local.ok
    for i in (1, 2):
        a = tmp_path / "dask" / f"flight{i}_comp.csv"
        b = tmp_path / "local" / f"flight{i}_comp.csv"
        assert a.read_bytes() == b.read_bytes()
        assert _report(a.with_suffix(".json")) == _report(b.with_suffix(".json"))
        ref = _single(logs / f"flight{i}.csv", tmp_path / "single", model=model)
        assert a.read_bytes() == ref.read_bytes()


def test_cli_batch_exit_status_summary_and_plan(logs, tmp_path):
    from aeromag.workflows.simulate import write_simulation

    sim = write_simulation(tmp_path / "sim", seed=1, small=True)
    runner = CliRunner()
    res = runner.invoke(app, ["batch", str(sim["survey"]), "--plan", str(sim["plan"]),
                              "-o", str(tmp_path / "o"), "--workers", "1", "--no-progress"])
    assert res.exit_code == 0, res.output
    for name in ("survey_comp.csv", "survey_comp.json", "survey_track.csv", "survey_track.json",
                 "batch_summary.csv", "batch_summary.json"):
        assert (tmp_path / "o" / name).exists(), name
    assert "legs" in json.loads((tmp_path / "o" / "survey_track.json").read_text())
    bad = runner.invoke(app, ["batch", str(logs / "empty.csv"), str(logs / "flight0.csv"),
                              "-o", str(tmp_path / "o2"), "--workers", "1", "--no-progress"])
    assert bad.exit_code == 1
    assert "empty.csv" in bad.output and "failed" in bad.output
    assert (tmp_path / "o2" / "flight0_comp.csv").exists()


def _cfg(**kw) -> CompensationConfig:
    return CompensationConfig(**kw)


def test_changed_options_or_model_reprocess_and_match_single_runs(logs, tmp_path):
    """The skip looks at the options, the model contents and the version, not only at times."""
    files = [logs / "flight0.csv"]
    out = tmp_path / "out"
    first = run_batch(files, out, cfg=_cfg(filter_output=False), workers=1, progress=False)
    assert first.results[0].status == SELF_FIT
    again = run_batch(files, out, cfg=_cfg(), workers=1, progress=False)
    assert again.results[0].status == SELF_FIT  # not "skipped": the --no-filter output is stale
    ref = _single(files[0], tmp_path / "single")
    assert (out / "flight0_comp.csv").read_bytes() == ref.read_bytes()
    assert _report(out / "flight0_comp.json") == _report(ref.with_suffix(".json"))
    assert run_batch(files, out, cfg=_cfg(), workers=1, progress=False).results[0].status \
        == "skipped"
    # Other column maps, units or formats are other runs too.
    assert run_batch(files, out, cfg=_cfg(), columns={"mag": "mag"}, workers=1,
                     progress=False).results[0].status == SELF_FIT
    # A model: its contents count, not its time stamp or name.
    m1, m2 = tmp_path / "m1.json", tmp_path / "m2.json"
    calibrate_file(logs / "flight1.csv", m1, CompensationConfig())
    calibrate_file(logs / "flight2.csv", m2, CompensationConfig())
    assert run_batch(files, out, model=m1, workers=1, progress=False).results[0].status == "ok"
    assert run_batch(files, out, model=m1, workers=1, progress=False).results[0].status \
        == "skipped"
    os.utime(m1)  # touched, same contents: still up to date
    assert run_batch(files, out, model=m1, workers=1, progress=False).results[0].status \
        == "skipped"
    m1.write_bytes(m2.read_bytes())  # same name, other model: redo
    assert run_batch(files, out, model=m1, workers=1, progress=False).results[0].status == "ok"
    ref = _single(files[0], tmp_path / "single_m2", model=m2)
    assert (out / "flight0_comp.csv").read_bytes() == ref.read_bytes()


def test_version_change_reprocesses(logs, tmp_path, monkeypatch):
    import aeromag

    files = [logs / "flight0.csv"]
    assert run_batch(files, tmp_path, workers=1, progress=False).results[0].status == SELF_FIT
    monkeypatch.setattr(aeromag, "__version__", aeromag.__version__ + ".post1")
    assert run_batch(files, tmp_path, workers=1, progress=False).results[0].status == SELF_FIT


def test_failed_rerun_is_never_skipped_later(logs, tmp_path):
    """A run that rewrote a file's outputs and then failed leaves no fingerprint behind."""
    files = [logs / "flight0.csv"]
    good = tmp_path / "plan.csv"
    good.write_text("lat,lon,alt\n47.3,8.5,500\n47.31,8.5,500\n")
    bad = tmp_path / "bad_plan.csv"
    bad.write_text("lat,lon,alt\n47.3,8.5,500\n")  # one waypoint: the track check fails
    out = tmp_path / "out"
    first = run_batch(files, out, cfg=_cfg(filter_output=False), workers=1, progress=False)
    assert first.results[0].status == SELF_FIT
    failed = run_batch(files, out, cfg=_cfg(), plan=bad, workers=1, progress=False)
    assert failed.results[0].status == "failed"  # compensation ran (default cfg), track failed
    assert not (out / ".flight0.batch.json").exists()
    redo = run_batch(files, out, cfg=_cfg(filter_output=False), workers=1, progress=False)
    assert redo.results[0].status == SELF_FIT


def test_cli_no_filter_then_default_is_not_up_to_date(logs, tmp_path):
    """The auditor's case: 'batch f.csv -o out --no-filter' then 'batch f.csv -o out'."""
    runner = CliRunner()
    f = str(logs / "flight0.csv")
    args = ["batch", f, "-o", str(tmp_path / "o"), "--workers", "1", "--no-progress"]
    r1 = runner.invoke(app, [*args, "--no-filter"])
    assert r1.exit_code == 0, r1.output
    r2 = runner.invoke(app, args)
    assert r2.exit_code == 0, r2.output
    assert "0 ok, 1 with warnings, 0 up to date" in r2.output  # self-fit: no box
    ref = _single(logs / "flight0.csv", tmp_path / "single")
    assert (tmp_path / "o" / "flight0_comp.csv").read_bytes() == ref.read_bytes()
    r3 = runner.invoke(app, args)
    assert "0 ok, 0 with warnings, 1 up to date" in r3.output


def test_summary_counts_are_integers(logs, tmp_path):
    summary = run_batch([logs / "flight0.csv", logs / "empty.csv"], tmp_path, workers=1,
                        progress=False)
    import csv

    with summary.summary_csv.open(newline="") as f:  # the warnings column holds commas
        header, *rows = list(csv.reader(f))
    row = dict(zip(header, rows[0], strict=True))
    assert row["n_rows"] == "4000"
    failed = dict(zip(header, rows[1], strict=True))
    assert failed["n_rows"] == "" and failed["flagged_legs"] == ""
    assert json.loads(summary.summary_json.read_text())["files"][0]["n_rows"] == 4000


def test_unmatched_inputs_say_why(tmp_path):
    (tmp_path / "empty_dir").mkdir()
    (tmp_path / "empty_dir" / "notes.md").write_text("no logs here")
    summary = run_batch([tmp_path / "empty_dir", str(tmp_path / "nope*.csv"),
                         tmp_path / "missing.csv"], tmp_path / "out", progress=False)
    err = {Path(r.input).name: r.error for r in summary.results}
    assert "folder holds no log files" in err["empty_dir"] and "*.csv" in err["empty_dir"]
    assert "*.parquet" in err["empty_dir"]
    assert "no file matches" in err["nope*.csv"]
    assert "no such file or folder" in err["missing.csv"]
    r = CliRunner().invoke(app, ["batch", str(tmp_path / "empty_dir"), "-o",
                                 str(tmp_path / "o"), "--no-progress"])
    assert r.exit_code == 1 and "folder holds no log files" in r.output


def test_outputs_never_overwrite_inputs(logs, tmp_path):
    out = tmp_path / "out"
    assert run_batch([logs / "flight0.csv"], out, workers=1, progress=False).ok
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    # A folder holding earlier outputs: batch_summary.csv would be overwritten.
    with pytest.raises(InputError, match="batch_summary.csv.*would overwrite"):
        run_batch([out], out, workers=1, progress=False)
    # One input's output is another input.
    with pytest.raises(InputError, match="would overwrite"):
        run_batch([logs / "flight0.csv", out / "flight0_comp.csv"], out, workers=1,
                  progress=False, force=True)
    # The plan is an output.
    plan = out / "flight0_track.csv"
    plan.write_text("lat,lon,alt\n47.3,8.5,500\n47.31,8.5,500\n")
    with pytest.raises(InputError, match="would overwrite the plan"):
        run_batch([logs / "flight0.csv"], out, plan=plan, workers=1, progress=False, force=True)
    plan.unlink()
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    r = CliRunner().invoke(app, ["batch", str(out), "-o", str(out), "--no-progress"])
    assert r.exit_code == 1 and r.output.startswith("error: ") and "would overwrite" in r.output
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_cli_extension_list_matches_the_library():
    from aeromag.cli import batch as cli_batch
    from aeromag.workflows.batch import LOG_EXTENSIONS

    assert cli_batch.LOG_EXTENSIONS == LOG_EXTENSIONS


# --------------------------------------------------------------------------- issue 15/16
DATA = Path(__file__).resolve().parents[1] / "data_samples"


def _mixed_folder(root: Path) -> Path:
    """Good logs (the survey; the calibration box), duplicates, a fluxgate in uT, a log
    without mag (and nothing that looks like one), a 13-row log and a corrupt one."""
    d = root / "mix"
    d.mkdir()
    df = pd.read_csv(DATA / "survey.csv")
    # Good: without their faulty line (survey line 2, box line 9), which the residual screen
    # of an applied model flags with a warning (issue 30; tests/test_residual_screen.py).
    df[df["line"] != 2].to_csv(d / "good.csv", index=False)
    cal = pd.read_csv(DATA / "calibration.csv")
    cal[cal["line"] != 9].to_csv(d / "box.csv", index=False)
    dup = pd.concat([df.iloc[:100], df.iloc[99:100], df.iloc[100:]], ignore_index=True)
    dup.to_csv(d / "dups.csv", index=False)
    micro = df.copy()
    micro[["flux_x", "flux_y", "flux_z"]] /= 1000.0
    micro.to_csv(d / "micro.csv", index=False)
    df[[c for c in df.columns if c != "mag" and not c.startswith("truth")]].to_csv(
        d / "nomag.csv", index=False)
    df.iloc[:13].to_csv(d / "short.csv", index=False)
    raw = (DATA / "survey.csv").read_bytes()
    (d / "corrupt.csv").write_bytes(raw[:20000] + b"\x00\xff garbage")
    return d


def _by_name(summary) -> dict:
    return {Path(r.input).name: r for r in summary.results}


@pytest.fixture(scope="module")
def mixed(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("mixed")
    model = root / "aircraft.json"
    calibrate_file(DATA / "calibration.csv", model)
    return _mixed_folder(root), model


def test_batch_mixed_folder_reports_each_file(mixed, tmp_path):
    """Issue 15: a folder mixing good logs, a uT log, a log without mag, a too-short log and
    a corrupt one: each reported for what it is (status, warnings column, reason), none dropped
    silently; duplicates are reported (issue 16).  With the box's model."""
    d, model = mixed
    summary = run_batch([d], tmp_path / "out", workers=2, progress=False, model=model)
    st = _by_name(summary)
    assert {n: r.status for n, r in st.items()} == {
        "good.csv": "ok", "box.csv": "ok", "dups.csv": "warn", "micro.csv": "warn",
        "nomag.csv": "failed", "short.csv": "failed", "corrupt.csv": "failed"}
    assert not st["good.csv"].warnings and not st["good.csv"].error
    assert any("dropped 1 exact duplicate row" in w for w in st["dups.csv"].warnings)
    assert st["dups.csv"].n_rows == 2010
    assert any("units={'flux': 'uT'}" in w for w in st["micro.csv"].warnings)
    assert st["micro.csv"].error is None
    # The model was fitted on the scalar: never applied to a fluxgate magnitude.
    assert "fitted on the scalar magnetometer" in st["nomag.csv"].error
    assert "too short to measure the compensation" in st["short.csv"].error
    assert "corrupt.csv: line 141: binary data" in st["corrupt.csv"].error
    assert not any("calibration box" in w for r in summary.results for w in r.warnings)
    for name in ("nomag", "short", "corrupt"):
        assert not (tmp_path / "out" / f"{name}_comp.csv").exists()
    frame = pd.read_csv(tmp_path / "out" / "batch_summary.csv", keep_default_na=False)
    frame = frame.set_index("input")
    row = frame.loc[str(d / "dups.csv")]
    assert row["status"] == "warn" and "duplicate" in row["warnings"]
    assert "units={'flux': 'uT'}" in frame.loc[str(d / "micro.csv"), "warnings"]
    assert "too short" in frame.loc[str(d / "short.csv"), "error"]
    rep = json.loads((tmp_path / "out" / "dups_comp.json").read_text())
    assert any("duplicate" in w for w in rep["warnings"])  # recorded in the file's JSON
    assert "self_calibration" not in rep  # a saved model: nothing fitted on the log
    summ = json.loads((tmp_path / "out" / "batch_summary.json").read_text())
    assert (summ["n_ok"], summ["n_warn"], summ["n_failed"]) == (2, 2, 3)
    assert not list((tmp_path / "out").glob(".*.tmp"))


def test_batch_self_fit_check_as_compensate_does(mixed, tmp_path):
    """Without --model every log is fitted on itself: batch checks for a calibration box as
    'aeromag compensate' does (it did not: the survey was "ok" with an in-sample headline and
    an undetermined level).  The box flight passes; the survey, the uT log and the log
    without mag warn, with the self_calibration block in their JSON."""
    d, _ = mixed
    summary = run_batch([d], tmp_path / "out", workers=2, progress=False)
    st = _by_name(summary)
    assert {n: r.status for n, r in st.items()} == {
        "good.csv": "warn", "box.csv": "ok", "dups.csv": "warn", "micro.csv": "warn",
        "nomag.csv": "warn", "short.csv": "failed", "corrupt.csv": "failed"}
    for name in ("good", "dups", "micro", "nomag"):
        assert any("without a calibration box" in w and "in-sample" in w
                   for w in st[f"{name}.csv"].warnings), name
        rep = json.loads((tmp_path / "out" / f"{name}_comp.json").read_text())
        assert rep["self_calibration"]["calibration_box"] is False
    assert any("fluxgate magnitude is the measured total field" in w
               for w in st["nomag.csv"].warnings)
    assert any("units={'flux': 'uT'}" in w for w in st["micro.csv"].warnings)
    assert not st["box.csv"].warnings
    box = json.loads((tmp_path / "out" / "box_comp.json").read_text())
    assert box["self_calibration"]["calibration_box"] is True
    assert "no continuous stretch is long enough" in st["short.csv"].error


def test_batch_strict_fails_each_warned_log_and_the_others_go_on(mixed, tmp_path):
    """--strict, per log: a log's warning is its error (status failed, the warning as the
    reason, none of its outputs), the clean logs are written, the command exits 1."""
    d, model = mixed
    out = tmp_path / "out"
    summary = run_batch([d], out, workers=2, progress=False, model=model, strict=True)
    st = _by_name(summary)
    assert {n: r.status for n, r in st.items()} == {
        "good.csv": "ok", "box.csv": "ok", "dups.csv": "failed", "micro.csv": "failed",
        "nomag.csv": "failed", "short.csv": "failed", "corrupt.csv": "failed"}
    assert "dropped 1 exact duplicate row" in st["dups.csv"].error
    assert "units={'flux': 'uT'}" in st["micro.csv"].error
    for name in ("dups", "micro"):
        err = st[f"{name}.csv"].error
        assert err.startswith(str(d / f"{name}.csv")) and "strict: warnings are errors" in err
        assert not (out / f"{name}_comp.csv").exists()
        assert not (out / f"{name}_comp.json").exists()
        assert not (out / f".{name}.batch.json").exists()
    assert (out / "good_comp.csv").exists() and (out / "box_comp.json").exists()
    # Self-fitted: only the box flight passes.
    selfs = _by_name(run_batch([d / "good.csv", d / "box.csv"], tmp_path / "self", workers=1,
                               progress=False, strict=True))
    assert selfs["box.csv"].status == "ok"
    assert selfs["good.csv"].status == "failed"
    assert "without a calibration box" in selfs["good.csv"].error
    assert not (tmp_path / "self" / "good_comp.csv").exists()
    # A lenient run's warned output is no strict run's: a strict rerun is no skip.
    lenient = run_batch([d / "micro.csv"], tmp_path / "again", workers=1, progress=False,
                        model=model)
    assert lenient.results[0].status == "warn"
    strict = run_batch([d / "micro.csv"], tmp_path / "again", workers=1, progress=False,
                       model=model, strict=True)
    assert strict.results[0].status == "failed"
    # The command line.
    r = CliRunner().invoke(app, ["batch", str(d / "good.csv"), str(d / "micro.csv"),
                                 "--model", str(model), "-o", str(tmp_path / "cli"),
                                 "--workers", "1", "--no-progress", "--strict"])
    assert r.exit_code == 1, r.output
    err = [ln for ln in r.output.splitlines() if ln.startswith("error: ")]
    assert len(err) == 1 and "micro.csv" in err[0] and "--units flux=uT" in err[0]
    assert (tmp_path / "cli" / "good_comp.csv").exists()


def test_metric_warnings():
    from aeromag.workflows.batch import metric_warnings

    assert metric_warnings(_m({"improvement_ratio": 10.0, "residual_std_nT": 0.2})) == []
    assert "< 1" in metric_warnings(_m({"improvement_ratio": 0.5, "residual_std_nT": 0.2}))[0]
    assert "implausibly small" in metric_warnings(_m({"improvement_ratio": 3,
                                                   "residual_std_nT": 0.0}))[0]
    assert "implausible" in metric_warnings(_m({"improvement_ratio": 3,
                                             "residual_std_nT": 500.0}))[0]
    assert "no residual" in metric_warnings(_m({"improvement_ratio": None}))[0]


def _descendants(pid: int) -> set[int]:
    """Every live descendant of ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for st in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = st.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        children.setdefault(int(fields[1]), []).append(int(st.parent.name))
    out, todo = set(), [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            if c not in out:
                out.add(c)
                todo.append(c)
    return out


def _alive(pids: set[int]) -> set[int]:
    alive = set()
    for p in pids:
        try:
            stat = Path(f"/proc/{p}/stat").read_text()
        except OSError:
            continue
        if stat.rsplit(")", 1)[1].split()[0] != "Z":
            alive.add(p)
    return alive


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
@pytest.mark.parametrize("sig", ["SIGKILL", "SIGINT"])
def test_batch_workers_die_with_the_parent_and_ctrl_c_is_prompt(tmp_path, sig):
    """Issue 16: killing only the batch parent (timeout, OOM killer) left its workers running
    for 60 s or more, and Ctrl-C drained the queue for ~10 s."""
    import signal
    import subprocess
    import sys
    import time

    d = tmp_path / "in"
    d.mkdir()
    raw = (DATA / "survey.csv").read_bytes()
    for i in range(10):
        (d / f"s{i}.csv").write_bytes(raw)
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "aeromag", "batch", str(d), "-o", str(out),
                             "--workers", "2"], cwd=tmp_path, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE)
    kids: set[int] = set()
    t_end = time.monotonic() + 60
    while time.monotonic() < t_end and len(kids) < 3 and proc.poll() is None:
        kids |= _descendants(proc.pid)
        time.sleep(0.1)
    assert proc.poll() is None and len(kids) >= 2, "the batch did not start its workers"
    time.sleep(0.5)
    t0 = time.monotonic()
    proc.send_signal(getattr(signal, sig))
    proc.wait(30)
    while _alive(kids) and time.monotonic() - t0 < 15:
        time.sleep(0.1)
    took = time.monotonic() - t0
    assert not _alive(kids), f"workers still running {took:.1f} s after {sig}"
    assert took < 8.0
    if sig == "SIGINT":
        assert proc.returncode != 0
        assert "Traceback" not in proc.stderr.read().decode()
    # nothing half-written: every output is complete or absent, no temporaries stay
    # (after SIGKILL only the parent died; the workers cleaned up their own files)
    assert not list(out.glob(".*.tmp")) if out.exists() else True
    for csv in out.glob("*_comp.csv") if out.exists() else []:
        assert csv.with_suffix(".json").exists()
        assert len(pd.read_csv(csv)) == 2010
