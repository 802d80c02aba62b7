"""``aeromag level``: lag, diurnal, IGRF removal, tie-line levelling, micro-levelling."""

from __future__ import annotations

import typer

from ._app import column_options, setup_logging, user_errors
from ._options import Options, command
from ._progress import progress_bar


@command("level")
def level(opts: Options) -> None:
    """Level a survey: the total-field anomaly per sample.

    Lag correction, diurnal correction from a base station (--base), IGRF-14 removal,
    tie-line levelling over every line-tie crossing (a robust, gradient-weighted network
    adjustment) and, with --decorrugate, micro-levelling.  Writes OUT (the log plus x_m, y_m,
    line_type, igrf, diurnal, tmi, tmi_lev, tmi_mlev) and OUT.json (crs, lag, igrf, diurnal,
    crossovers, mistie std before and after, the correction per line).
    """
    setup_logging(opts.verbose)
    from ..io import json_path_for
    from ..workflows.level import level_file

    with user_errors():
        columns, unit_map = column_options(opts.col, opts.map_file, opts.units)
        with progress_bar("level", enabled=False if opts.no_progress else None) as progress:
            res = level_file(opts.survey, opts.output, plot_dir=opts.plot,
                             base=opts.base or None, value=opts.value, date=opts.date,
                             lag=opts.lag, igrf=not opts.no_igrf, ties=opts.ties,
                             method=opts.level_method, decorrugate=opts.decorrugate,
                             crs=opts.crs, base_datum_nT=opts.base_datum,
                             allow_base_gaps=opts.allow_base_gaps, columns=columns,
                             units=unit_map, fmt=opts.fmt, progress=progress)
    std = res.mistie_std_nT
    line = f"wrote {opts.output} and {json_path_for(opts.output)}"
    if res.crossings is not None:
        line += f": {res.crossings.n} crossings"
        if std.before is not None:
            line += f", mistie std {std.before:.2f} -> {std.after:.2f} nT"
    if res.lag_estimate is not None:
        line += f"; lag {res.lag_s:.3f} +- {res.lag_estimate.std_s:.3f} s"
    typer.echo(line)
