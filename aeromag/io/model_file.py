"""Model JSON and column-map TOML files: read with a size limit, validated against a schema.

A model file (written by ``aeromag calibrate``) is a JSON object with ``terms`` (term names of
the Tolles-Lawson model, each at most once, in the contract's order), ``coef`` (one finite
number per term, nT or nT*s), an optional ``scale_nT`` (the ``|B|`` scale, positive and finite,
50000 by default) and the fit report.  A column map is a TOML file with a ``[columns]`` table
(canonical name = source column) and an optional ``[units]`` table.  Both are user input: they
are read from regular files only (never a device such as ``/dev/zero``), at most
:data:`MAX_MODEL_BYTES` / :data:`MAX_MAP_BYTES`, as UTF-8, with bounded nesting, and every
value is checked, so that a bad file is a one-line error naming what to fix, never a traceback
or an absurd model.
"""

from __future__ import annotations

import json
import math
import os
import stat
import tomllib
from pathlib import Path
from typing import Any

from ..errors import InputError
from .messages import clean
from .outputs import register_input
from .units import unit_factor

#: Largest model file read [bytes] (a calibration's report with per-segment scores is ~100 kB).
MAX_MODEL_BYTES = 32 << 20
#: Largest column-map file read [bytes].
MAX_MAP_BYTES = 1 << 20
#: Deepest nesting of arrays / objects accepted in a model or map file.
MAX_DEPTH = 32
#: Most entries of a column map.
MAX_MAP_ENTRIES = 1000

_REMEDY = "pass a model file written by 'aeromag calibrate'"


def read_limited(path: str | os.PathLike[str], limit: int, what: str) -> str:
    """The text of a regular UTF-8 file of at most ``limit`` bytes.

    Parameters
    ----------
    path : path-like
        The file.
    limit : int
        Largest size accepted [bytes].
    what : str
        What the file is, for messages (``"model file"``).

    Returns
    -------
    str
    """
    p = Path(path)
    try:
        st = os.stat(p)
    except FileNotFoundError:
        hint = (" (write one with 'aeromag calibrate CAL.csv -o MODEL.json')"
                if "model" in what else "")
        raise InputError(f"{clean(p)}: {what} not found; check the path{hint}") from None
    except OSError as exc:
        raise InputError(f"{clean(p)}: cannot read the {what} ({exc.strerror or exc})") from None
    if stat.S_ISDIR(st.st_mode):
        raise InputError(f"{clean(p)}: is a folder; give the {what} itself")
    if not stat.S_ISREG(st.st_mode):
        raise InputError(f"{clean(p)}: not a regular file (a device, FIFO or socket); give a"
                         f" {what} on disk")
    try:
        with open(p, "rb") as fh:
            data = fh.read(limit + 1)
    except OSError as exc:
        raise InputError(f"{clean(p)}: cannot read the {what} ({exc.strerror or exc})") from None
    if len(data) > limit:
        raise InputError(f"{clean(p)}: larger than {limit >> 20} MB: not a {what}; check the"
                         " path")
    try:
        return data.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        raise InputError(f"{clean(p)}: byte {exc.start} is not UTF-8 text: not a {what}; save it"
                         " as UTF-8") from None


def _depth(obj: Any, limit: int = MAX_DEPTH) -> int:
    """Nesting depth of lists / dicts (iterative; stops counting past ``limit``)."""
    deepest = 0
    stack = [(obj, 1)]
    while stack:
        o, d = stack.pop()
        if isinstance(o, dict | list):
            deepest = max(deepest, d)
            if deepest > limit:
                return deepest
            stack.extend((v, d + 1) for v in (o.values() if isinstance(o, dict) else o))
    return deepest


def _known_terms() -> tuple[str, ...]:
    from ..compensation.terms import BIAS, EDDY_9, INDUCED_6, PERMANENT

    return PERMANENT + INDUCED_6 + EDDY_9 + BIAS


def _finite(x: float) -> bool:
    try:
        return math.isfinite(float(x))
    except OverflowError:  # an integer beyond float range
        return False


def validate_model_document(d: Any, source: str = "<model>") -> dict[str, Any]:
    """Check a model document against the schema; return it (``scale_nT`` made a float).

    Parameters
    ----------
    d : object
        The parsed JSON.
    source : str
        File name quoted in errors.

    Returns
    -------
    dict

    Raises
    ------
    InputError
        Not an object; ``terms`` not a list of known, distinct term names (1 to 19);
        ``coef`` not one finite number per term; ``scale_nT`` not a positive finite number;
        nesting deeper than :data:`MAX_DEPTH`; a recorded fit setting out of range
        (``band_hz``, ``sampling_rate_hz``, ``filter_order``, ``mag_from_fluxgate``).
    """
    src = clean(source)
    if not isinstance(d, dict):
        raise InputError(f"{src}: not a model file (a JSON object is expected); {_REMEDY}")
    if _depth(d) > MAX_DEPTH:
        raise InputError(f"{src}: nested more than {MAX_DEPTH} levels deep: not a model file;"
                         f" {_REMEDY}")
    terms, coef = d.get("terms"), d.get("coef")
    if not isinstance(terms, list) or not isinstance(coef, list):
        raise InputError(f"{src}: not a model file (needs 'terms' and 'coef' lists); {_REMEDY}")
    known = _known_terms()
    if not 1 <= len(terms) <= len(known):
        raise InputError(f"{src}: {len(terms)} terms; a model has 1 to {len(known)} of"
                         f" {', '.join(known)}; {_REMEDY}")
    bad = [t for t in terms if not isinstance(t, str) or t not in known]
    if bad:
        raise InputError(f"{src}: unknown term {clean(repr(bad[0]))[:60]}; the terms are"
                         f" {', '.join(known)}; {_REMEDY}")
    dup = next((t for i, t in enumerate(terms) if t in terms[:i]), None)
    if dup is not None:
        raise InputError(f"{src}: term {dup!r} appears more than once; each term at most once;"
                         f" {_REMEDY}")
    if len(coef) != len(terms):
        raise InputError(f"{src}: {len(terms)} terms but {len(coef)} coefficients; {_REMEDY}")
    for name, c in zip(terms, coef, strict=True):
        if isinstance(c, bool) or not isinstance(c, int | float) or not _finite(c):
            raise InputError(f"{src}: coefficient of {name!r} is {clean(repr(c))[:40]}, not a"
                             f" finite number; {_REMEDY}")
    scale = d.get("scale_nT", 50000.0)
    if (isinstance(scale, bool) or not isinstance(scale, int | float)
            or not _finite(scale) or scale <= 0):
        raise InputError(f"{src}: scale_nT is {clean(repr(scale))[:40]}; it must be a positive"
                         f" number of nT (50000 by the contract); {_REMEDY}")
    d["scale_nT"] = float(scale)
    _check_fit_settings(d, src)
    return d


def _number(x: Any) -> bool:
    return not isinstance(x, bool) and isinstance(x, int | float) and _finite(x)


def _check_fit_settings(d: dict[str, Any], src: str) -> None:
    """Check the fit settings a model records (each optional, null allowed).

    ``band_hz`` two increasing positive numbers [Hz], ``sampling_rate_hz`` a positive number
    [Hz], ``filter_order`` a whole number 1 to 20, ``mag_from_fluxgate`` true or false.
    """
    band = d.get("band_hz")
    if band is not None and not (isinstance(band, list) and len(band) == 2
                                 and all(_number(b) for b in band) and 0 < band[0] < band[1]):
        raise InputError(f"{src}: the pass band it records is {clean(repr(band))[:60]}; it"
                         f" must be [LOW, HIGH] in Hz with 0 < LOW < HIGH; {_REMEDY}")
    fs = d.get("sampling_rate_hz")
    if fs is not None and not (_number(fs) and fs > 0):
        raise InputError(f"{src}: sampling_rate_hz is {clean(repr(fs))[:40]}; it must be a"
                         f" positive number of Hz; {_REMEDY}")
    order = d.get("filter_order")
    if order is not None and not (_number(order) and float(order).is_integer()
                                  and 1 <= order <= 20):
        raise InputError(f"{src}: filter_order is {clean(repr(order))[:40]}; it must be a"
                         f" whole number from 1 to 20; {_REMEDY}")
    mff = d.get("mag_from_fluxgate")
    if mff is not None and not isinstance(mff, bool):
        raise InputError(f"{src}: mag_from_fluxgate is {clean(repr(mff))[:40]}; it must be"
                         f" true or false; {_REMEDY}")


def read_model_document(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read and validate a model JSON file (see :func:`validate_model_document`).

    The model becomes an input of the running command: no output may overwrite it.

    Parameters
    ----------
    path : path-like
        The model file.

    Returns
    -------
    dict
    """
    p = Path(path)
    text = read_limited(p, MAX_MODEL_BYTES, "model file")
    register_input(p, "model")
    try:
        d = json.loads(text, parse_constant=_no_constant)
    except (json.JSONDecodeError, RecursionError) as exc:
        why = exc.msg if isinstance(exc, json.JSONDecodeError) else "nested too deeply"
        where = f" at line {exc.lineno}" if isinstance(exc, json.JSONDecodeError) else ""
        raise InputError(f"{clean(p)}: not valid JSON ({why}{where}); {_REMEDY}") from None
    except ValueError as exc:  # NaN / Infinity constants, huge integers
        raise InputError(f"{clean(p)}: {clean(exc)}; {_REMEDY}") from None
    return validate_model_document(d, str(p))


def _no_constant(name: str) -> float:
    raise ValueError(f"{name} is not a number a model may hold")


def read_map_file(path: str | os.PathLike[str]) -> tuple[dict[str, str], dict[str, str]]:
    """Read and validate a TOML column-map file: ``([columns], [units])``.

    The file holds a ``[columns]`` table (canonical name = source column) and an optional
    ``[units]`` table (column or group = unit), for example::

        [columns]
        mag = "mag_1_uc"
        flux_x = "flux_b_x"

        [units]
        flux = "uT"

    Parameters
    ----------
    path : path-like
        The TOML file.

    Returns
    -------
    columns, units : dict, dict
        ``{canonical: source}`` and ``{column_or_group: unit}`` (units checked).
    """
    p = Path(path)
    src = clean(p)
    text = read_limited(p, MAX_MAP_BYTES, "column-map file")
    register_input(p, "column map")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{src}: not a valid TOML column map ({clean(exc)}); write [columns]"
                         ' with NAME = "SOURCE" lines') from None
    except RecursionError:
        raise InputError(f"{src}: nested too deeply: not a column map") from None
    if _depth(data) > 3:
        raise InputError(f"{src}: nested tables or arrays: a column map is [columns] and"
                         ' [units] tables of NAME = "VALUE"')
    extra = [k for k in data if k not in ("columns", "units")]
    if extra:
        raise InputError(f"{src}: unknown table or key {clean(extra[0])!r}; a column map has only"
                         " [columns] and [units]")
    out = []
    for table in ("columns", "units"):
        t = data.get(table, {})
        if not isinstance(t, dict):
            raise InputError(f"{src}: [{table}] must be a table of NAME = \"VALUE\"")
        if len(t) > MAX_MAP_ENTRIES:
            raise InputError(f"{src}: [{table}] has {len(t)} entries (at most"
                             f" {MAX_MAP_ENTRIES})")
        for k, v in t.items():
            if not isinstance(v, str) or not v.strip() or not k.strip():
                raise InputError(f"{src}: [{table}] {clean(k)!r} = {clean(repr(v))[:40]}: write"
                                 ' NAME = "VALUE" with a non-empty text value')
        out.append({str(k).strip(): str(v).strip() for k, v in t.items()})
    columns, units = out
    for k, u in units.items():
        unit_factor(u, what=f"{src}: [units] {clean(k)}")
    return columns, units
