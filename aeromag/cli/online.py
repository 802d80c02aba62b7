"""``aeromag compensate --online``: the option rows and the dispatch to the online workflow.

Imported by :mod:`aeromag.cli.compensate` before its command is registered, so the three rows
below are part of the one option table (:mod:`aeromag.cli._options`).
"""

from __future__ import annotations

import typer

from ..errors import InputError
from ._app import column_options, setup_logging, strict_warnings, user_errors
from ._options import OPTIONS, Option, Options, add_option

_ONLINE = frozenset({"compensate"})

if "online" not in {o.name for o in OPTIONS}:
    add_option(Option(
        "online", ("--online",), bool, False,
        "Fit the model sample by sample (recursive least squares with a forgetting factor, "
        "causal), for interference that changes during the flight; no screening.", _ONLINE),
        before="model")
    add_option(Option(
        "forgetting", ("--forgetting",), float | None, None,
        "With --online: forgetting factor lambda, 0 < L <= 1 (1: plain recursive least "
        "squares; default 0.999, a memory of about 1000 samples).", _ONLINE, metavar="L"),
        before="model")
    add_option(Option(
        "mark_unconverged", ("--mark-unconverged",), bool, False,
        "With --online: write segment_kept false on the rows issued before the fit "
        "converged (the first memory, and after a change of the interference found by the "
        "windowed NIS of the a-priori residuals; OUT.json convergence.spans). Without it "
        "those rows are kept and each change is a warning.", _ONLINE),
        before="model")


def run_online(opts: Options) -> None:
    """Run ``compensate --online`` with the parsed options of ``compensate``.

    Parameters
    ----------
    opts : Options
        The options of the ``compensate`` command.
    """
    setup_logging(opts.verbose)
    from ..io import json_path_for
    from ..workflows.online_compensate import DEFAULT_FORGETTING, compensate_online_file

    with user_errors(), strict_warnings(bool(opts.get("strict", False))):
        for name, flag in (("model", "--model"), ("chunk_rows", "--chunk-rows"),
                           ("plot", "--plot")):
            if opts.get(name) is not None:
                raise InputError(f"{flag} does not go with --online (the online fit estimates "
                                 f"the model as it goes); drop {flag}")
        opts.refuse_unused_options()  # --ridge, --noise-factor...: no batch fit, no screening
        columns, unit_map = column_options(opts.col, opts.map_file, opts.units)
        cfg = opts.config()
        lam = DEFAULT_FORGETTING if opts.get("forgetting") is None else opts.forgetting
        report = compensate_online_file(opts.survey, opts.output, cfg, forgetting=lam,
                                        columns=columns, units=unit_map,
                                        fmt=opts.get("fmt"),
                                        mark_unconverged=bool(opts.get("mark_unconverged")))
    m = report.metrics
    typer.echo(f"wrote {opts.output} and {json_path_for(opts.output)}: online fit, lambda "
               f"{report.forgetting:g}, improvement ratio {m.improvement_ratio:.2f}, "
               f"residual {m.residual_std_nT:.3f} nT")


def dispatch(opts: Options) -> bool:
    """Run the online fit when ``--online`` is given; refuse ``--forgetting`` without it.

    Parameters
    ----------
    opts : Options
        The options of the ``compensate`` command.

    Returns
    -------
    bool
        True when the online fit ran (the batch path must not).
    """
    if opts.get("online"):
        run_online(opts)
        return True
    if opts.get("forgetting") is not None:
        with user_errors():
            raise InputError("--forgetting applies to the online fit: add --online")
    if opts.get("mark_unconverged"):
        with user_errors():
            raise InputError("--mark-unconverged applies to the online fit: add --online")
    return False
