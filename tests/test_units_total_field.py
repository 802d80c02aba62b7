"""Issue 30: a total field in uT or G (the scalar, or the fluxgate magnitude when it is the
total field) is an error naming ``--units mag=UNIT`` in every compensation path; before, a
log with ``mag`` and ``flux_*`` both in uT gave "residual std 0.0001 nT" (exit 0)."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from typer.testing import CliRunner

from aeromag.cli import app

DATA = Path(__file__).resolve().parents[1] / "data_samples"
runner = CliRunner()
FLUX = ["flux_x", "flux_y", "flux_z"]


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    d = tmp_path_factory.mktemp("units")
    df = pd.read_csv(DATA / "survey.csv")
    df = df.drop(columns=[c for c in df.columns if c.startswith("truth_")])
    ut = df.copy()
    ut[[*FLUX, "mag"]] /= 1000.0
    ut.to_csv(d / "ut.csv", index=False)
    g = df.copy()
    g["mag"] /= 1e5
    g.to_csv(d / "gauss.csv", index=False)
    flux_only = df.drop(columns=["mag"])
    flux_only[FLUX] /= 1000.0
    flux_only.to_csv(d / "flux_ut.csv", index=False)
    model = d / "model.json"
    assert runner.invoke(app, ["calibrate", str(DATA / "calibration.csv"), "-o",
                               str(model)]).exit_code == 0
    model_flux = d / "model_flux.json"
    assert runner.invoke(app, ["calibrate", str(DATA / "calibration.csv"), "-o",
                               str(model_flux), "--mag-from-fluxgate"]).exit_code == 0
    return d, model, model_flux


PATHS = {"fit": [], "model": ["--model", "{model}"],
         "chunked": ["--model", "{model}", "--chunk-rows", "500"], "online": ["--online"],
         "calibrate": None}


@pytest.mark.parametrize("path", list(PATHS))
@pytest.mark.parametrize(("name", "flag"), [("ut.csv", "--units mag=uT"),
                                            ("gauss.csv", "--units mag=G"),
                                            ("flux_ut.csv", "--units flux=uT")])
def test_a_total_field_in_another_unit_is_refused(logs, path, name, flag):
    d, model, model_flux = logs
    m = model_flux if name == "flux_ut.csv" else model
    if PATHS[path] is None:
        args = ["calibrate", str(d / name), "-o", str(d / f"{path}_{name}.json")]
    else:
        args = ["compensate", str(d / name), "-o", str(d / f"{path}_{name}"),
                *[a.format(model=m) for a in PATHS[path]]]
    if name == "flux_ut.csv" and path != "model" and path != "chunked":
        args.append("--mag-from-fluxgate")
    r = runner.invoke(app, args)
    assert r.exit_code == 1, r.output
    line = r.output.strip().splitlines()[-1]
    assert line.startswith(f"error: {d / name}: ") and flag in line, line
    assert not (d / f"{path}_{name}").exists()


def test_a_fluxgate_in_ut_beside_a_scalar_in_nt_still_only_warns(logs, tmp_path):
    """The scalar sets the level: the fluxgate's unit only scales the model's |B| terms."""
    df = pd.read_csv(DATA / "survey.csv")
    df[FLUX] /= 1000.0
    p = tmp_path / "micro.csv"
    df.to_csv(p, index=False)
    r = runner.invoke(app, ["compensate", str(p), "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 0, r.output
    warned = json.loads((tmp_path / "o.json").read_text())["warnings"]
    assert any("--units flux=uT" in w for w in warned)
