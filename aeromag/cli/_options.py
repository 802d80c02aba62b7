"""The one option table of the command line: every option declared once.

Each :class:`Option` says which commands take it (``commands``) and, for the compensation
options, which :class:`~aeromag.compensation.config.CompensationConfig` keyword it sets
(``config``).  A command is a plain function of one argument, the parsed options; the
:func:`command` decorator gives typer the signature built from the table's rows for that
command, so a new option is one row here (and a new command one name in ``commands``)::

    @command("compensate")
    def compensate(opts: Options) -> None:
        cfg = opts.config()          # CompensationConfig from the rows that set one
        ...

:func:`config_errors` turns a library :class:`~aeromag.compensation.config.ConfigError`
(which names the parameter, e.g. ``band_hz``) into a message naming the flag (``--band``).
Nothing here imports the library at module level, so ``aeromag --help`` stays fast.
"""

from __future__ import annotations

import contextlib
import inspect
import logging
import re
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

import typer

from ..errors import InputError
from ._typer import app

__all__ = ["OPTIONS", "Option", "Options", "add_option", "command", "config_errors",
           "flag_batch_summary", "flag_message", "flag_messages"]

_REQUIRED = inspect.Parameter.empty

#: Log-reading commands (``--col``, ``--map``, ``--units``, ``--format``).
_READERS = frozenset({"compensate", "calibrate", "batch", "level"})
#: Commands that fit or apply the TL model.
_COMP = frozenset({"compensate", "calibrate", "batch"})
_APPLY = frozenset({"compensate", "batch"})
#: Commands that fit on one log (the extended fit's options).
_FIT = frozenset({"compensate", "calibrate"})

# Same as aeromag.workflows.batch.LOG_EXTENSIONS (a test checks it); literal here so that
# 'aeromag --help' does not import pandas.
LOG_EXTENSIONS = (".csv", ".txt", ".parquet", ".pq", ".xyz", ".h5", ".hdf5")


@dataclass(frozen=True)
class Option:
    """One row of the option table.

    Attributes
    ----------
    name : str
        Python name of the parameter (what :class:`Options` is indexed by).
    flags : tuple of str
        Command-line flags (empty for a positional argument).
    type : object
        Python type typer converts the value to.
    default : object
        Default value (``_REQUIRED``: must be given).
    help : str or mapping
        Help text, or one per command name.
    commands : frozenset of str
        Commands that take the option.
    metavar : str or mapping, optional
        Metavariable shown in the help, or one per command.
    config : str, optional
        The :class:`CompensationConfig` keyword the option sets.
    to_config : callable, optional
        Value -> keyword value (``--no-screen`` sets ``screen=not value``).
    extra : dict
        Further keywords for ``typer.Option`` / ``typer.Argument``.
    """

    name: str
    flags: tuple[str, ...]
    type: Any
    default: Any
    help: str | Mapping[str, str]
    commands: frozenset[str]
    metavar: str | Mapping[str, str] | None = None
    config: str | None = None
    to_config: Callable[[Any], Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def _for(self, value: Any, cmd: str) -> Any:
        return value.get(cmd) if isinstance(value, Mapping) else value

    def parameter(self, cmd: str) -> inspect.Parameter:
        """The typer parameter of this option for command ``cmd``."""
        kw = dict(help=self._for(self.help, cmd), metavar=self._for(self.metavar, cmd),
                  **self.extra)
        info = typer.Option(*self.flags, **kw) if self.flags else typer.Argument(
            show_default=False, **kw)
        return inspect.Parameter(self.name, inspect.Parameter.KEYWORD_ONLY,
                                 default=self.default, annotation=Annotated[self.type, info])


def _o(name: str, flags: str | tuple[str, ...], typ: Any, default: Any, help: str | Mapping,
       commands: frozenset[str] | set[str], **kw: Any) -> Option:
    flags = (flags,) if isinstance(flags, str) else flags
    return Option(name, flags, typ, default, help, frozenset(commands), **kw)


#: The table.  Order is the order of the options in each command's help.
OPTIONS: list[Option] = [
    # positional arguments
    _o("survey", (), Path, _REQUIRED,
       {"compensate": "Survey log (CSV, or another --format).",
        "level": "Survey log with time, lat, lon, alt, line and a total field (CSV, or another "
                 "--format)."}, {"compensate", "level"}, metavar="SURVEY.csv"),
    _o("cal", (), Path, _REQUIRED, "Calibration flight log (CSV, or another --format).",
       {"calibrate"}, metavar="CAL.csv"),
    _o("inputs", (), list[str], _REQUIRED, "Logs: files, globs or folders (a folder's "
       f"{', '.join('*' + e for e in LOG_EXTENSIONS)} files).", {"batch"}, metavar="INPUTS"),
    # outputs and models
    _o("output", "-o", Path, _REQUIRED,
       {"compensate": "Output log: CSV, or Parquet / Geosoft XYZ by the extension (.parquet,"
                      " .xyz); the report goes to OUT.json (OUT.parquet.json, OUT.xyz.json).",
        "calibrate": "Output model file (JSON).",
        "batch": "Output folder (NAME_comp.csv/.json per log, batch_summary.csv/.json).",
        "level": "Output log: .csv, .parquet or .xyz (Geosoft XYZ with a Line/Tie header per "
                 "line); the report goes to OUT.json."},
       _COMP | {"level"}, metavar={"compensate": "OUT.csv", "calibrate": "MODEL.json",
                                   "batch": "OUTDIR", "level": "OUT.csv"}),
    _o("model", "--model", Path | None, None,
       {"compensate": "Apply a saved model (from 'aeromag calibrate') instead of fitting.",
        "batch": "Apply this saved model to every log (default: self-calibrate each log like "
                 "'compensate')."}, _APPLY, metavar="MODEL.json"),
    _o("plan", "--plan", Path | None, None, "Mission plan: also run the track check per log "
       "(NAME_track.csv/.json).", {"batch"}, metavar="PLAN.csv"),
    _o("workers", "--workers", int | None, None, "Local worker processes (default: all cores).",
       {"batch"}, metavar="N"),
    _o("scheduler", "--scheduler", str | None, None, "Run on a Dask cluster, e.g. "
       "tcp://host:8786 (pip install 'aeromag[dask]').", {"batch"}, metavar="ADDRESS"),
    _o("force", "--force", bool, False, "Re-process every log (by default a log is skipped when "
       "its outputs are newer than it and were made with the same options, model, plan and "
       "aeromag version).", {"batch"}),
    _o("threshold", "--threshold", float, 1.0, "Track alarm threshold, metres (with --plan).",
       {"batch"}, metavar="M"),
    # survey levelling ('aeromag level'; grid has its own grid_value and grid_crs rows)
    _o("value", "--value", str | None, None,
       {"level": "The column to level (default: mag_comp when the log has it, else mag)."},
       {"level"}, metavar="COL"),
    _o("base", "--base", list[Path] | None, None, "Base-station record: CSV with time (UTC s "
       "since 1970 or ISO 8601) and mag (nT), IAGA-2002 .min/.sec (F, or F from the vector "
       "components), a GEM GSM-19 base file or a Geometrics G-856 dump (with --date); "
       "repeatable for consecutive days. Without it: no diurnal correction (a "
       "warning says so).", {"level"}, metavar="FILE"),
    _o("base_datum", "--base-datum", float | None, None, "Datum of the diurnal correction, nT "
       "(default: the base's mean over the survey).", {"level"}, metavar="NT"),
    _o("allow_base_gaps", "--allow-base-gaps", bool, False, "Samples outside the base record's "
       "coverage get an empty diurnal (and tmi) with a warning, instead of an error (never "
       "extrapolated).", {"level"}),
    _o("date", "--date", str | None, None, "The UTC date of a log whose time is seconds since "
       "midnight (level: also the year of a G-856 base dump).", {"level"}, metavar="YYYY-MM-DD"),
    _o("lag", "--lag", str, "0", "The magnetometer's lag behind the position, s (positive when "
       "the reading at time t is the field at the position of time t - lag), or auto: "
       "estimated from adjacent lines flown in opposite directions.", {"level"},
       metavar="S|auto"),
    _o("no_igrf", "--no-igrf", bool, False, "The value is already an anomaly: no IGRF removed.",
       {"level"}),
    _o("ties", "--ties", str, "auto", "Which lines are tie lines: auto (a line_type column when "
       "the log has one, else lines roughly perpendicular to the dominant direction) or "
       "ID,ID,...", {"level"}, metavar="auto|ID,..."),
    _o("level_method", "--level", str, "trend", "Tie-line levelling: trend (a shift per tie, a "
       "shift and a linear trend per line with 3+ crossings), shift, smooth (piecewise linear "
       "along lines, knots every 5 km), or none (tmi_lev = tmi).", {"level"},
       metavar="METHOD"),
    _o("decorrugate", "--decorrugate", bool, False, "Also micro-level (remove the "
       "line-parallel corrugation that tie-line levelling leaves): tmi_mlev.", {"level"}),
    _o("crs", "--crs", int | None, None, "Projected coordinate system, EPSG code (default: the "
       "UTM zone of the survey's centre).", {"level"}, metavar="EPSG"),
    # filters, terms, segments
    _o("band", "--band", tuple[float, float], (0.1, 0.9),
       "Band-pass applied before fitting, Hz (zero-phase Butterworth).", _COMP,
       metavar="LOW HIGH", config="band_hz"),
    _o("terms", "--terms", str, "16", "Term set: 16 (default), 18, 9, or groups like "
       "permanent,induced_5,eddy_8[,bias] (MagNav spellings such as induced5, eddy8 too).",
       _COMP, metavar="SET", config="terms"),
    _o("segment_seconds", "--segment-seconds", float, 60.0,
       "Segment length when the log has no 'line' column, s.", _COMP, metavar="S",
       config="segment_seconds"),
    _o("no_screen", "--no-screen", bool, False, "Skip PCA screening (fit all segments).", _COMP,
       config="screen", to_config=lambda v: not v),
    _o("no_decimate", "--no-decimate", bool, False, "Fit every sample of a high-rate log "
       "(default: fit a copy decimated to >= 80x the band's upper edge, anti-aliased per "
       "stretch; see docs/compensation.md).", _COMP, config="decimate",
       to_config=lambda v: not v),
    _o("no_filter", "--no-filter", bool, False, "Leave mag_comp unfiltered.", _APPLY,
       config="filter_output", to_config=lambda v: not v),
    _o("lowpass", "--lowpass", float | None, None, "Cut-off of the final low-pass on mag_comp, "
       "Hz (default: the band's upper edge).", _APPLY, metavar="HZ", config="lowpass_hz"),
    # reading logs
    _o("col", "--col", list[str] | None, None, "Column map, repeatable (e.g. mag=mag_1_uc).",
       _READERS, metavar="NAME=SOURCE"),
    _o("map_file", "--map", Path | None, None, "TOML column map: [columns] NAME = \"SOURCE\", "
       "optional [units] NAME = \"UNIT\".", _READERS, metavar="FILE"),
    _o("units", "--units", list[str] | None, None,
       "Convert a field column or group (flux, mag) from nT/uT/mT/G to nT.", _READERS,
       metavar="NAME=UNIT"),
    _o("allow_truncated", "--allow-truncated", bool, False, "Drop a last row cut short (a log "
       "that ended in the middle of a row) with a warning in OUT.json, instead of refusing the "
       "log.", _READERS),
    # the fit and its checks
    _o("ridge", "--ridge", float, 0.0, "Relative ridge parameter (0 = plain LS).", _COMP,
       config="ridge"),
    _o("max_condition", "--max-condition", float, 1e5, "Refuse an unregularised fit whose "
       "scaled condition number exceeds K (a box calibration gives ~1e2; straight-and-level "
       "flight ~1e5-1e6).", _COMP, metavar="K", config="max_condition"),
    _o("max_interference", "--max-interference", float, 0.25, "Refuse a fitted model whose "
       "|mag_tl| (99th percentile) exceeds this fraction of the Earth field (non-physical: the "
       "flight did not determine it).", _COMP, metavar="FRACTION", config="max_interference"),
    # compensation beyond the 16 terms (aeromag.compensation.extended)
    _o("reference", "--reference", str | None, None, "Fit the interference against mag - COL "
       "(a reference total field, nT: a compensated stinger, a map) over the full band, with an "
       "intercept, instead of the band-passed self-fit.", _FIT, metavar="COL",
       config="reference"),
    _o("extra", "--extra", str | None, None, "More regressors beside the TL terms, comma-"
       "separated (aircraft currents, voltages...): fitted like them and saved in the model.",
       _FIT, metavar="COL,...", config="extras"),  # split by CompensationConfig
    _o("estimator", "--estimator", str, "ridge", "Fit of --reference/--extra: ridge, pls, or "
       "mlp (a small network correcting the linear fit; with --reference; kept only when it "
       "lowers the held-out error).", _FIT, metavar="ridge|pls|mlp", config="estimator"),
    # screening
    _o("shrink", "--shrink", float, 1.0, "Shrinkage of per-segment fits toward the pooled fit "
       "during screening (0 = none).", _COMP, config="shrink"),
    _o("pca_variance", "--pca-variance", float, 0.8, "Cumulative explained variance of the PCA "
       "components used for screening.", _COMP, config="pca_variance"),
    _o("screen_quantile", "--screen-quantile", float, 0.975, "Chi-square quantile of the "
       "screening cut-off on the robust distance.", _COMP, config="screen_quantile"),
    _o("min_excess", "--min-excess", float, 1.5, "A PCA outlier is dropped only when the pooled "
       "fit leaves it a residual above this times the median segment's.", _COMP,
       config="min_excess"),
    _o("min_excess_nt", "--min-excess-nt", float, 0.01, "... and by at least this much in nT, "
       "and by --noise-factor standard deviations of the in-band noise: an excess inside the "
       "sensor noise is kept.", _COMP, config="min_excess_nT"),
    _o("noise_factor", "--noise-factor", float, 3.0, "... and by at least K standard deviations "
       "of the in-band noise (K dimensionless; the noise, nT, is the median residual the kept "
       "segments' own fits leave): the floor is max(--min-excess-nt, K x noise); 0 turns the "
       "noise floor off.", _COMP, metavar="K", config="noise_factor"),
    # stretches
    _o("max_gap", "--max-gap", float | None, None, "A time step longer than this starts a new "
       "stretch, s (default 5 dt).", _COMP, metavar="S", config="max_gap_s"),
    _o("max_interp", "--max-interp", float, 1.0, "NaN gaps up to this long are interpolated, s; "
       "longer ones split stretches.", _COMP, metavar="S", config="max_interp_s"),
    _o("mag_from_fluxgate", "--mag-from-fluxgate", bool, False, "Take the fluxgate magnitude "
       "as the measured total field even when the log has a 'mag' column or a column that "
       "looks like a misnamed scalar (a log without either uses it, with a warning).", _COMP,
       config="mag_from_fluxgate"),
    _o("fmt", "--format", str | None, None, "Input format (default: from the extension and "
       "contents; see docs/formats.md).", _READERS, metavar="FORMAT"),
    _o("fom", "--fom", bool, False, "Detect maneuvers and report the Figure of Merit (for a "
       "calibration-style flight).", {"compensate"}, config="fom",
       to_config=lambda v: v or None),
    _o("plot", "--plot", Path | None, None,
       {"compensate": "Also write the QC figures (PNG) and report.html into DIR.",
        "calibrate": "Also write the QC figures (PNG) and report.html into DIR.",
        "level": "Also write the levelling QC figures (misties.png: mistie histograms before "
                 "and after; profiles.png: stacked line profiles) into DIR."},
       {"compensate", "calibrate", "level"},
       metavar="DIR"),
    _o("chunk_rows", "--chunk-rows", int | None, None,
       {"compensate": "With --model: apply it in chunks of N rows, memory bounded by the chunk "
                      "size (identical output; for very large logs).",
        "batch": "With --model: apply it in chunks of N rows (bounded memory for very large "
                 "logs)."}, _APPLY, metavar="N"),
    _o("strict", "--strict", bool, False,
       {"compensate": "Treat every warning (units that do not look like nT, a fit that leaves "
                      "more than it removes, ...) as an error: exit 1, no output.",
        "calibrate": "Treat every warning (units that do not look like nT, a fit that leaves "
                     "more than it removes, ...) as an error: exit 1, no output.",
        "batch": "Treat every warning of a log as its error: that log fails with the warning "
                 "as its reason and no outputs; the others go on (exit 1 when any failed)."},
       {"compensate", "calibrate", "batch"}),
    _o("no_progress", "--no-progress", bool, False, "No progress bar.", {"batch", "level"}),
    _o("verbose", ("-v", "--verbose"), bool, False,
       "Log progress details (DEBUG messages of aeromag's loggers).", _COMP | {"level"}),
]


def add_option(option: Option, *, before: str | None = None) -> None:
    """Add a row to the table (before the row named ``before``, default at the end).

    Call it before the command module that uses it is imported (rows are read when the
    command is registered).

    Parameters
    ----------
    option : Option
        The new row.
    before : str, optional
        Name of the row it goes before.
    """
    names = [o.name for o in OPTIONS]
    if option.name in names:
        raise ValueError(f"option {option.name!r} is declared already")
    OPTIONS.insert(names.index(before) if before in names else len(OPTIONS), option)


class Options(dict):
    """The parsed options of one command (``opts["band"]``, ``opts.band``).

    Parameters
    ----------
    command : str
        The command's name.
    values : mapping
        Parameter name -> value, as typer parsed them.
    """

    def __init__(self, command: str, values: Mapping[str, Any],
                 given: frozenset[str] | None = None) -> None:
        super().__init__(values)
        self.command = command
        #: Names of the options given on the command line (None: unknown, e.g. in tests).
        self.given = given

    def refuse_unused_options(self) -> None:
        """Refuse, in one line, a fit, screening or filter option that this run would not use.

        The rule is the library's (:func:`~aeromag.compensation.config.unused_options`, which
        :func:`aeromag.compensate` and :func:`aeromag.calibrate` apply to a Python caller's
        configuration); here it names flags and counts an option as given when it was typed,
        even at its default value.  With ``--model`` nothing is fitted (``--terms``,
        ``--ridge``, the screening options...); with ``--online`` the recursive fit uses
        ``--terms`` but no batch-fit option (``--ridge``, ``--max-condition``,
        ``--no-decimate``, ``--no-screen``), screens nothing and reports no FOM (``--fom``);
        with ``--no-screen`` the screening's thresholds (``--noise-factor``,
        ``--min-excess``...) decide nothing; with ``--no-filter`` ``--lowpass`` does nothing.
        ``--shrink`` stays allowed with ``--no-screen``: it still shrinks the per-segment
        coefficients OUT.json reports.

        Raises
        ------
        InputError
            Naming the first such option given and what to drop.
        """
        from ..compensation.config import unused_options

        rows = {o.config: i for i, o in enumerate(OPTIONS)
                if o.config and o.flags and o.name in self}
        given = {o.config for o in OPTIONS if o.config in rows and (
            o.name in self.given if self.given is not None else self[o.name] != o.default)}
        found = unused_options(self.config(), model=self.get("model") is not None,
                               online=bool(self.get("online")), given=given)
        if not found:
            return
        first = min((u for u in found if u.cause == found[0].cause),
                    key=lambda u: rows[u.keyword])
        cond, undo = _CLI_SPELLING[first.cause]
        raise InputError(first.message(OPTIONS[rows[first.keyword]].flags[-1], cond, undo))

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None

    def config(self, **overrides: Any) -> Any:
        """The :class:`CompensationConfig` of the rows of this command that set one.

        Parameters
        ----------
        **overrides
            Keywords set on top of the options.

        Returns
        -------
        CompensationConfig
        """
        from ..compensation.config import CompensationConfig

        kw: dict[str, Any] = {}
        for opt in OPTIONS:
            if opt.config and opt.name in self:
                v = self[opt.name]
                kw[opt.config] = opt.to_config(v) if opt.to_config else v
        kw.update(overrides)
        with config_errors():
            return CompensationConfig(**kw)


#: ``{cond}`` and ``{undo}`` of :data:`aeromag.compensation.config.UNUSED_MESSAGES` in flags.
_CLI_SPELLING = {
    "model": ("--model", "or drop --model to fit"),
    "online": ("--online", "or drop --online"),
    "online_fom": ("--online", "aeromag report on the output gives the FOM of a calibration box"),
    "screen": ("--no-screen", "or drop --no-screen"),
    "filter": ("--no-filter", "or drop --no-filter"),
}


def _flag_text(value: Any) -> str:
    if isinstance(value, tuple | list):
        return " ".join(_flag_text(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


#: Library keywords that are no CompensationConfig field, and their flags (the detectors'
#: own parameter names too: ``heading_detector(sigmas=...)`` is ``track --heading-sigmas``).
_KEYWORD_FLAGS = {"model": "--model", "chunk_rows": "--chunk-rows",
                  "allow_truncated": "--allow-truncated", "forgetting": "--forgetting",
                  "mark_unconverged": "--mark-unconverged",
                  "earth_field": "--earth-field", "calm_window": "--calm-window",
                  "sigmas": "--heading-sigmas", "heading_sigmas": "--heading-sigmas",
                  "sigma_floor_deg": "--heading-sigma-floor",
                  "heading_sigma_floor_deg": "--heading-sigma-floor",
                  "n_particles": "--particles", "window": "--window",
                  "threshold": "--threshold", "scheduler": "--scheduler",
                  "gps": "--gps", "fmt": "--format", "threshold_m": "--threshold",
                  "min_duration_s": "--min-duration", "combine": "--combine",
                  "altitude_offset": "--altitude-offset", "horizontal": "--horizontal"}
#: Reading keywords (mappings) and their flags: ``columns={'K': 'V'}`` is ``--col K=V``.
_DICT_FLAGS = {"columns": "--col", "units": "--units"}
#: Keywords given as a tuple: ``earth_field=(F, I, D)`` is ``--earth-field F I D``;
#: ``calm_window=(10, 40)`` is ``--calm-window 10:40`` (:data:`_TUPLE_JOIN`).
_TUPLE_FLAGS = {"earth_field": "--earth-field", "origin": "--origin",
                "calm_window": "--calm-window", "gps": "--gps"}
#: How a tuple's values are written after its flag (default: separate words).
_TUPLE_JOIN = {"calm_window": ":", "gps": ":"}
#: Keywords given as a string: ``date='2024-06-01'`` is ``--date 2024-06-01``.
_STRING_FLAGS = {"date": "--date", "calm_window": "--calm-window", "gps": "--gps",
                 "scheduler": "--scheduler", "combine": "--combine",
                 "altitude_offset": "--altitude-offset"}


def _tuple_flag(name: str, values: str) -> str:
    """``earth_field``, ``'54000.0, 57, -5'`` -> ``--earth-field 54000 57 -5``."""
    parts = []
    for v in values.split(","):
        v = v.strip()
        try:
            parts.append(f"{float(v):g}")
        except ValueError:
            parts.append(v)  # a placeholder: F, I, D
    join = _TUPLE_JOIN.get(name)
    return " ".join([_TUPLE_FLAGS[name], *parts]) if join is None else (
        f"{_TUPLE_FLAGS[name]} {join.join(parts)}")


def _as_flag(name: str, value: str = "") -> str:
    """``segment_seconds=120`` -> ``--segment-seconds 120``; ``screen=False`` -> ``--no-screen``."""
    opt = next((o for o in OPTIONS if o.config == name and o.flags), None)
    if opt is None:
        flag = _KEYWORD_FLAGS[name]  # a switch: allow_truncated=True is --allow-truncated
        return f"{flag} {value}" if value not in ("", "True") else flag
    flag = opt.flags[-1]
    if opt.type is bool and value in ("True", "False"):
        on = opt.to_config(True) if opt.to_config else True
        return flag if str(on) == value else f"no {flag}"
    return f"{flag} {value}" if value else flag


def flag_message(message: str) -> str:
    """A library message with its keywords (``ridge=1e-3``) spelled as command-line flags.

    Library errors name the parameter a caller sets (``segment_seconds=...``); the command
    line says ``--segment-seconds ...``.  Keywords are rewritten in their ``name=value`` form
    (and bare when the name has an underscore, which no English word has); mappings, tuples
    and strings in their Python spelling: ``columns={'mag': 'mag_1_uc'}`` is ``--col
    mag=mag_1_uc``, ``earth_field=(F, I, D)`` is ``--earth-field F I D``, ``origin=(LAT, LON,
    ALT)`` is ``--origin LAT LON ALT`` and ``date='2024-06-01'`` is ``--date 2024-06-01``.

    Parameters
    ----------
    message : str
        The library's message.

    Returns
    -------
    str
    """
    names = sorted({o.config for o in OPTIONS if o.config and o.flags} | set(_KEYWORD_FLAGS),
                   key=len, reverse=True)
    alt = "|".join(re.escape(n) for n in names)
    # The reading keywords: columns={'mag': 'mag_1_uc'} -> --col mag=mag_1_uc, units=... too.
    message = re.sub(r"(?<![\w-])(columns|units)=(?:\{'([^']*)': '([^']*)'\}|\.\.\.)",
                     lambda m: _DICT_FLAGS[m[1]] + (f" {m[2]}={m[3]}" if m[2] is not None
                                                    else ""), message)
    # The reference field and frame: earth_field=(F, I, D), origin=(...), date='YYYY-MM-DD'.
    message = re.sub(rf"(?<![\w-])({'|'.join(_TUPLE_FLAGS)})=\(([^()]*)\)",
                     lambda m: _tuple_flag(m[1], m[2]), message)
    message = re.sub(rf"(?<![\w-])({'|'.join(_STRING_FLAGS)})='([^']*)'",
                     lambda m: f"{_STRING_FLAGS[m[1]]} {m[2]}", message)
    message = re.sub(rf"(?<![\w-])({alt})=([^\s,;:)]*)", lambda m: _as_flag(*m.groups()),
                     message)
    bare = "|".join(re.escape(n) for n in names if "_" in n)
    return re.sub(rf"(?<![\w-])({bare})(?![\w=-])", lambda m: _as_flag(m.group(1)), message)


@contextlib.contextmanager
def config_errors() -> Iterator[None]:
    """Re-raise library errors naming the command-line flags instead of the keywords.

    A :class:`ConfigError` becomes ``FLAG VALUE: reason``; any other
    :class:`~aeromag.errors.AeromagError` has its ``name=value`` keywords rewritten
    (:func:`flag_message`).
    """
    from ..compensation.config import ConfigError
    from ..errors import AeromagError

    try:
        yield
    except ConfigError as exc:
        flag = next((o.flags[-1] for o in OPTIONS if o.config == exc.parameter and o.flags),
                    exc.parameter)
        raise InputError(f"{flag} {_flag_text(exc.value)}: {exc.reason}") from None
    except AeromagError as exc:
        if len(exc.args) == 1 and isinstance(exc.args[0], str):
            exc.args = (flag_message(exc.args[0]),)
        raise


def _library_record(name: str) -> bool:
    """Whether a logger is the library's (``aeromag.*`` but not the command line's own)."""
    return (name == "aeromag" or name.startswith("aeromag.")) and not (
        name == __package__ or name.startswith(f"{__package__}."))


@contextlib.contextmanager
def flag_messages() -> Iterator[None]:
    """While open, the library's warnings name command-line flags (:func:`flag_message`).

    The library names the parameter a Python caller sets (``units={'flux': 'uT'}``); on the
    command line the same warning says ``--units flux=uT``.  The message is rewritten where
    the record is made, so every consumer sees the same text: the terminal, the warnings
    recorded in OUT.json (:mod:`aeromag.io.outputs`) and ``--strict``'s error.  Records of
    ``aeromag.cli`` (which name flags already) and below WARNING are left as they are.
    """
    old = logging.getLogRecordFactory()

    def factory(*args: Any, **kwargs: Any) -> logging.LogRecord:
        rec = old(*args, **kwargs)
        if rec.levelno >= logging.WARNING and _library_record(rec.name):
            try:
                msg = rec.getMessage()
            except Exception:  # noqa: BLE001 - a bad format string is logging's to report
                return rec
            new = flag_message(msg)
            if new != msg:
                rec.msg, rec.args = new, None
        return rec

    logging.setLogRecordFactory(factory)
    try:
        yield
    finally:
        logging.setLogRecordFactory(old)


def flag_batch_summary(summary: Any) -> bool:
    """Spell the reasons and warnings of a batch run with command-line flags.

    :func:`~aeromag.workflows.batch.run_batch` collects each log's error and warnings from its
    worker process, in the library's words (``columns={'mag': 'mag_1_uc'}``); ``aeromag
    batch`` shows them as ``--col mag=mag_1_uc`` like ``aeromag compensate`` does.  The
    results are rewritten in place and, when any text changed, ``batch_summary.csv`` and
    ``batch_summary.json`` are written again with the same contents otherwise; so is the
    ``warnings`` list of each log's reports (``NAME_comp.json``, ``NAME_track.json``), which
    a worker process recorded in the library's words.

    Parameters
    ----------
    summary : BatchSummary
        What ``run_batch`` returned (its summary files written).

    Returns
    -------
    bool
        Whether any message changed.
    """
    import json
    from dataclasses import asdict

    from ..io import write_csv, write_json

    changed = False
    for r in summary.results:
        err = flag_message(r.error) if r.error else r.error
        warns = [flag_message(w) for w in r.warnings]
        if err != r.error or warns != r.warnings:
            r.error, r.warnings, changed = err, warns, True
            for out in (Path(o) for o in r.outputs if str(o).endswith(".json")):
                if not out.is_file():
                    continue
                rep = json.loads(out.read_text(encoding="utf-8"))
                old = rep.get("warnings") if isinstance(rep, dict) else None
                if isinstance(old, list) and any(isinstance(w, str) for w in old):
                    new = [flag_message(w) if isinstance(w, str) else w for w in old]
                    if new != old:
                        rep["warnings"] = new
                        write_json(rep, out)
    if not changed:
        return False

    if summary.summary_csv is not None:
        write_csv(summary.to_frame(), summary.summary_csv)
    if summary.summary_json is not None and Path(summary.summary_json).is_file():
        doc = json.loads(Path(summary.summary_json).read_text(encoding="utf-8"))
        doc["files"] = [asdict(r) for r in summary.results]
        write_json(doc, summary.summary_json)
    return True


def command(name: str, **typer_kw: Any) -> Callable[[Callable[[Options], None]], Callable]:
    """Register ``body(opts)`` as command ``name`` with the table's options for it.

    Parameters
    ----------
    name : str
        The command's name (rows whose ``commands`` hold it are its options).
    **typer_kw
        Passed to ``app.command`` (e.g. ``help``).

    Returns
    -------
    callable
        The decorator.
    """

    def deco(body: Callable[[Options], None]) -> Callable:
        rows = [o for o in OPTIONS if name in o.commands]
        params = [o.parameter(name) for o in rows]
        params.insert(0, inspect.Parameter("_typer_ctx", inspect.Parameter.KEYWORD_ONLY,
                                           annotation=typer.Context))

        def run(_typer_ctx: typer.Context, **values: Any) -> None:
            from ..io.log import reading_options

            # Which options were typed (not defaults): --model refuses fit-only ones.
            given = frozenset(k for k in values if getattr(
                _typer_ctx.get_parameter_source(k), "name", None) == "COMMANDLINE")
            with reading_options(allow_truncated=bool(values.get("allow_truncated"))):
                body(Options(name, values, given))

        run.__name__ = name
        run.__doc__ = body.__doc__
        run.__signature__ = inspect.Signature(params)  # type: ignore[attr-defined]
        run.__annotations__ = {p.name: p.annotation for p in params}
        app.command(name, **typer_kw)(run)
        return body

    return deco
