"""aeromag batch: per-file isolation, equality with single runs, Dask, skipping, CLI."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.batch import expand_inputs, run_batch
from aeromag.cli import app
from aeromag.compensate import CompensationConfig, calibrate_file, compensate_file
from aeromag.io import write_csv

from .conftest import hand_flight


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
    target = out / f"{log.stem}_comp.csv"
    compensate_file(log, target, CompensationConfig(), **kw)
    return target


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
        assert status[f"flight{i}.csv"].status == "ok"
        ref = _single(logs / f"flight{i}.csv", single)
        got = tmp_path / "out" / f"flight{i}_comp.csv"
        assert got.read_bytes() == ref.read_bytes()
        assert _report(got.with_suffix(".json")) == _report(ref.with_suffix(".json"))
    frame = pd.read_csv(summary.summary_csv)
    assert list(frame["status"]).count("failed") == 2
    js = json.loads(summary.summary_json.read_text())
    assert js["n_failed"] == 2 and js["n_ok"] == 3


def test_skip_up_to_date_and_force(logs, tmp_path):
    files = [logs / "flight0.csv"]
    first = run_batch(files, tmp_path, workers=1, progress=False)
    assert first.results[0].status == "ok"
    again = run_batch(files, tmp_path, workers=1, progress=False)
    assert again.results[0].status == "skipped"
    forced = run_batch(files, tmp_path, workers=1, progress=False, force=True)
    assert forced.results[0].status == "ok"
    os.utime(files[0])  # the input changed after the outputs: redo
    assert run_batch(files, tmp_path, workers=1, progress=False).results[0].status == "ok"


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
    simulate = pytest.importorskip("aeromag.simulate")
    sim = simulate.write_simulation(tmp_path / "sim", seed=1, small=True)
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
