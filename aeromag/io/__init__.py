"""Everything that touches a file: reading and writing survey logs, column maps, units,
atomic outputs and reports.

Used by :mod:`aeromag.workflows` and :mod:`aeromag.cli` only, never by the numerics.

=================  ===============================================================
module             what it holds
=================  ===============================================================
``columns``        canonical columns, column maps and map files, unit conversion,
                   numbers from text (with the file line of a bad value)
``rows``           where the data rows of a table are in its file (for messages)
``csv``            the one CSV reader (``csv_write``: the one CSV writer)
``formats``        the one registry of formats: extension, sniffing, read, write
                   (CSV, Parquet, Geosoft XYZ, MagNav/SGL HDF5, MagArrow, MagDrone)
``log``            :func:`read_log`: any format into validated canonical columns
``stream``         row batches for the chunked mode, validated by ``log``'s functions
``outputs``        atomic writes as a set (all files or none), stale temporaries, -o checks
``json``           JSON reports and models (a report records the command's warnings)
``model_file``     model JSON and column-map TOML: size limits and schema
``messages``       echoed names without control characters
``plans``          mission plans (``.csv``, QGroundControl ``.plan``, ``.waypoints``)
``base``           base-station records: CSV ``time,mag`` and IAGA-2002 (``.min``, ``.sec``)
``base_dumps``     GEM GSM-19 base files and Geometrics G-856 dumps (content-sniffed)
=================  ===============================================================
"""

from . import (
    base,  # noqa: F401 - registers the iaga2002 format (base-station records)
    uav_logs,  # noqa: F401 - registers the ulog and dataflash formats
)
from .columns import (
    CANONICAL_COLUMNS,
    FIELD_UNITS_TO_NT,
    FLUX_COLUMNS,
    NUMERIC_COLUMNS,
    UNIT_GROUPS,
    apply_column_map,
    check_unique_names,
    convert_units,
    datetime_seconds,
    filled_cells,
    numeric_values,
    parse_column_map,
    plain_number,
    unit_factor,
)
from .csv import (
    EXTRA_FIELD,  # noqa: F401 - kept for callers of the old aeromag.io
    PASSTHROUGH_BLOCK_BYTES,
    UNNAMED_FIELD,  # noqa: F401 - kept for callers of the old aeromag.io
    first_data_fields,  # noqa: F401 - kept for callers of the old aeromag.io
    read_csv,
    read_csv_arrow,  # noqa: F401 - kept for callers of the old aeromag.io
)
from .csv_write import (
    csv_header,  # noqa: F401 - kept for callers of the old aeromag.io
    floats_as_pandas_text,  # noqa: F401 - kept for callers of the old aeromag.io
    write_arrow_csv,
    write_csv,
    write_csv_passthrough,
)
from .json import write_json
from .log import read_log, reading_options
from .model_file import read_map_file, read_model_document
from .outputs import atomic_path, check_outputs, json_path_for, output_set
from .rows import (
    ROWS_ATTR,
    row_location,
    rows_after_header,
    rows_in_runs,
    rows_numbered,
)

__all__ = [
    "CANONICAL_COLUMNS", "FIELD_UNITS_TO_NT", "FLUX_COLUMNS", "NUMERIC_COLUMNS",
    "PASSTHROUGH_BLOCK_BYTES", "ROWS_ATTR", "UNIT_GROUPS",
    "apply_column_map", "atomic_path", "check_outputs", "check_unique_names", "convert_units",
    "datetime_seconds", "filled_cells", "json_path_for", "numeric_values",
    "output_set", "parse_column_map", "plain_number", "read_csv", "read_log", "read_map_file",
    "read_model_document", "reading_options",
    "row_location", "rows_after_header", "rows_in_runs", "rows_numbered", "unit_factor",
    "write_arrow_csv", "write_csv", "write_csv_passthrough", "write_json",
]
