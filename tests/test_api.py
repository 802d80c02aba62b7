"""The public API (``import aeromag as am``), no old import paths, the option table, config
groups and the CLI's logging switch (issue 10)."""

from __future__ import annotations

import logging
import subprocess
import sys
import types

import pytest
from typer.testing import CliRunner

import aeromag as am
from aeromag.cli import app

runner = CliRunner()

#: The old flat modules (forwarders removed: 0.1.0 was never published).
OLD = ("batch", "chunked", "compensate", "detect", "estimator", "filters", "formats", "maneuvers",
       "report", "screening", "segments", "simulate", "simulate_mission", "tolles_lawson", "warm")


def _python(code: str, *flags: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, *flags, "-c", code], capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("old", OLD)
def test_old_flat_modules_are_gone_and_public_names_stay_functions(old):
    import importlib

    with pytest.raises(ModuleNotFoundError):
        importlib.import_module(f"aeromag.{old}")
    if old in am.__all__:  # am.compensate: the function
        assert not isinstance(getattr(am, old), types.ModuleType)


def test_all_lists_the_public_api_and_every_name_resolves():
    assert len(am.__all__) == len(set(am.__all__))
    assert len(am.__all__) <= 45, f"{len(am.__all__)} public names: move some to a subpackage"
    for name in ("read_log", "compensate", "calibrate", "TollesLawsonRegressor", "TLModel",
                 "CompensationConfig", "check_track", "write_report", "level", "grid"):
        assert name in am.__all__, name
    for name in am.__all__:
        assert getattr(am, name) is not None, name
    assert set(am.__all__) <= set(dir(am))
    with pytest.raises(AttributeError, match="no attribute 'simulate_survey'"):
        am.simulate_survey  # noqa: B018  (simulators live in am.synthetic)
    p = _python("import aeromag as am; print(am.__all__)")
    assert p.returncode == 0 and "'compensate'" in p.stdout, p.stderr


@pytest.mark.parametrize("sub", ["synthetic", "estimation", "plot", "workflows"])
def test_public_subpackages_list_names_that_resolve(sub):
    mod = getattr(am, sub)
    assert isinstance(mod, types.ModuleType) and mod.__name__ == f"aeromag.{sub}"
    assert mod.__all__ and len(mod.__all__) == len(set(mod.__all__))
    for name in mod.__all__:
        assert getattr(mod, name) is not None, f"{sub}.{name}"
        assert name not in am.__all__, f"{name} is both am.{name} and am.{sub}.{name}"
    with pytest.raises(AttributeError):
        mod.no_such_name  # noqa: B018


def test_subpackages_hold_the_moved_names_and_the_renames():
    assert am.synthetic.simulate_growth.__module__ == "aeromag.synthetic.benchmarks"
    assert am.synthetic.simulate_cstr.__module__ == "aeromag.synthetic.benchmarks"
    assert am.estimation.SequentialResult.__module__ == "aeromag._core.sequential"
    assert callable(am.workflows.report_file) and callable(am.plot.plot_psd)
    for gone in ("TollesLawson", "OnlineTollesLawson", "OnlineTL", "build_report"):
        assert gone not in am.__all__ and not hasattr(am, gone), gone
    assert am.TollesLawsonRegressor().__class__.__name__ == "TollesLawsonRegressor"


def test_docs_api_md_is_current():
    """``docs/api.md`` is what ``python docs/make_api.py`` writes today (run it after a change)."""
    import importlib.util
    from pathlib import Path

    docs = Path(__file__).resolve().parents[1] / "docs"
    spec = importlib.util.spec_from_file_location("make_api", docs / "make_api.py")
    make_api = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_api)
    page = make_api.render()
    assert (docs / "api.md").read_text() == page, "stale: run python docs/make_api.py"
    assert "| `path` | path-like |" in page  # parameters, not only summaries
    assert "## Survey chain" in page and "### `am.estimation.ParticleFilter`" in page


def test_import_aeromag_is_light():
    """The flat API imports on first use: ``import aeromag`` loads neither pandas nor scipy."""
    p = _python("import sys, aeromag; print(sorted(m for m in ('pandas', 'scipy', 'sklearn',"
                " 'matplotlib') if m in sys.modules))")
    assert p.returncode == 0 and p.stdout.strip() == "[]", p.stdout + p.stderr


def test_config_groups_and_flat_keywords_agree():
    from aeromag.compensation.config import (
        CompensationConfig,
        ConfigError,
        FilterOptions,
        FitChecks,
        ScreeningOptions,
    )

    flat = CompensationConfig(band_hz=(0.2, 1.0), shrink=0.5, max_condition=1e4, terms="9")
    grouped = CompensationConfig.from_groups(filter=FilterOptions(band_hz=(0.2, 1.0)),
                                             screening=ScreeningOptions(shrink=0.5),
                                             checks=FitChecks(max_condition=1e4), terms="9")
    assert flat == grouped
    assert flat.filter.band_hz == (0.2, 1.0) and flat.screening.shrink == 0.5
    assert flat.checks.max_condition == 1e4 and flat.segments.segment_seconds == 60.0
    with pytest.raises(ConfigError, match="^pca_variance=") as err:
        ScreeningOptions(pca_variance=2.0)
    assert err.value.parameter == "pca_variance"


def test_cli_names_the_flag_of_a_bad_value(tmp_path):
    src = tmp_path / "x.csv"
    src.write_text("time,flux_x,flux_y,flux_z\n0,1,2,3\n")
    for cmd, extra in (("compensate", ["-o", str(tmp_path / "o.csv")]),
                       ("calibrate", ["-o", str(tmp_path / "m.json")])):
        r = runner.invoke(app, [cmd, str(src), *extra, "--band", "0.5", "0.1"])
        assert r.exit_code == 1
        assert r.output.strip() == "error: --band 0.5 0.1: need 0 < LOW < HIGH in Hz", r.output
    r = runner.invoke(app, ["batch", str(src), "-o", str(tmp_path / "b"), "--pca-variance",
                            "3"])
    assert r.exit_code == 1 and "--pca-variance 3: must be in (0, 1]" in r.output, r.output


def test_option_table_gives_each_command_its_options():
    from aeromag.cli._options import OPTIONS

    def flags(cmd: str) -> set[str]:
        return {f for o in OPTIONS if cmd in o.commands for f in o.flags}

    comp, cal, batch = flags("compensate"), flags("calibrate"), flags("batch")
    shared = {"--band", "--terms", "--segment-seconds", "--no-screen", "--ridge", "--shrink",
              "--pca-variance", "--screen-quantile", "--min-excess", "--min-excess-nt",
              "--max-gap", "--max-interp", "--max-condition", "--max-interference", "--col",
              "--map", "--units", "--format", "-o", "-v"}
    assert shared <= comp and shared <= cal and shared <= batch
    assert {"--model", "--no-filter", "--lowpass", "--chunk-rows"} <= comp & batch
    assert not {"--model", "--no-filter", "--chunk-rows"} & cal
    assert {"--plan", "--workers", "--threshold"} <= batch - comp
    names = [o.name for o in OPTIONS]
    assert len(names) == len(set(names))
    r = runner.invoke(app, ["batch", "--help"], terminal_width=100)
    assert "--shrink" in r.output and "--pca-variance" in r.output


def test_options_build_the_configuration():
    from aeromag.cli._options import Options

    cfg = Options("batch", {"band": (0.2, 0.8), "no_screen": True, "shrink": 0.3,
                            "no_filter": True, "fmt": None}).config()
    assert cfg.band_hz == (0.2, 0.8) and cfg.screen is False and cfg.shrink == 0.3
    assert cfg.filter_output is False


def test_verbose_is_debug_for_aeromag_only():
    from aeromag.cli._app import setup_logging

    try:
        setup_logging(True)
        assert logging.getLogger("aeromag.compensation.fit").isEnabledFor(logging.DEBUG)
        assert not logging.getLogger("matplotlib.font_manager").isEnabledFor(logging.DEBUG)
        assert logging.getLogger("matplotlib").isEnabledFor(logging.WARNING)
        setup_logging(False)
        assert not logging.getLogger("aeromag.compensation.fit").isEnabledFor(logging.INFO)
        assert logging.getLogger("aeromag.compensation.fit").isEnabledFor(logging.WARNING)
    finally:
        logging.getLogger("aeromag").setLevel(logging.NOTSET)


def test_magnav_term_spellings():
    from aeromag.compensation.terms import TERMS_16, parse_terms

    assert parse_terms("permanent,induced5,eddy8") == TERMS_16
    assert parse_terms(":permanent,:induced_5,:eddy_8") == TERMS_16
    assert len(parse_terms("p,i6,e9")) == 18


def test_api_page_is_generated_from_all():
    import importlib.util
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "docs" / "make_api.py"
    spec = importlib.util.spec_from_file_location("make_api", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    page = mod.render()
    for name in am.__all__:
        if not name.startswith("__"):
            assert f"`am.{name}`" in page, name


def test_maneuver_spelling_with_old_aliases():
    from aeromag import synthetic

    assert synthetic.MANEUVERS == synthetic.MANOEUVRES == ("pitch", "roll", "yaw")
    assert synthetic.MANEUVER_AMPLITUDE_DEG is synthetic.MANOEUVRE_AMPLITUDE_DEG
    new, _ = synthetic.simulate_calibration(seed=1, n_boxes=1, maneuver_s=8.0)
    old, _ = synthetic.simulate_calibration(seed=1, n_boxes=1, manoeuvre_s=8.0)
    assert new.equals(old) and len(new) < len(synthetic.simulate_calibration(seed=1,
                                                                              n_boxes=1)[0])


def test_cli_maps_library_keywords_to_flags(tmp_path, flight):
    """The library says segment_seconds=..., the command line --segment-seconds ..."""
    from aeromag.cli._options import flag_message

    assert flag_message("use a longer segment_seconds=... or regularise with ridge=1e-3,"
                        " or mag_from_fluxgate=True, screen=False, band_hz, model=MODEL") == (
        "use a longer --segment-seconds ... or regularise with --ridge 1e-3, or"
        " --mag-from-fluxgate, --no-screen, --band, --model MODEL")
    df, _ = flight
    src = tmp_path / "short.csv"
    df.iloc[:150].drop(columns=["line"], errors="ignore").to_csv(src, index=False)
    r = runner.invoke(app, ["compensate", str(src), "-o", str(tmp_path / "o.csv")])
    assert r.exit_code == 1 and r.output.startswith("error: "), r.output
    assert "segment_seconds" not in r.output and "=" not in r.output.split("line column")[0], \
        r.output


def test_result_repr_is_short(flight):
    df, _ = flight
    res = am.calibrate(df)
    text = repr(res)
    assert len(text) < 300 and "improvement_ratio=" in text and "\n" not in text, text
    html = res._repr_html_()
    assert html.startswith("<table>") and len(html) < 3000
