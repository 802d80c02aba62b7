"""The report's reader holds no allocator overhead a test can see (issue 15 item 11).

Not timed and not RSS-based: the frame's dtypes (``segment`` int32, the drawn-only columns
float32), arrays of numpy's own (no pyarrow buffer kept alive), and pyarrow's default
mimalloc pool, which keeps freed blocks resident, not used by the read (a fresh process,
so that pool's high-water mark starts at zero).
"""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from aeromag.synthetic import simulate_calibration
from aeromag.workflows import _report_read as rep
from aeromag.workflows.compensate import compensate_file


@pytest.fixture(scope="module")
def out_csv(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("mem3")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        df, _ = simulate_calibration(seed=3, n_boxes=1)
    df.to_csv(d / "cal.csv", index=False)
    compensate_file(d / "cal.csv", d / "out.csv")
    return d / "out.csv"


_PROBE = """
import json, sys
from pathlib import Path
import numpy as np
import pyarrow as pa
from aeromag.workflows import _report_read as rep
before = pa.default_memory_pool().backend_name
mi = pa.mimalloc_memory_pool()
d = rep.read_columns(Path(sys.argv[1]))
owned = {c: d[c].to_numpy().base is None or isinstance(d[c].to_numpy().base, np.ndarray)
         for c in d.columns}
print(json.dumps({"mimalloc_max": mi.max_memory(), "before": before,
                  "after": pa.default_memory_pool().backend_name,
                  "system_held": pa.system_memory_pool().bytes_allocated(),
                  "owned": owned, "dtypes": {c: str(t) for c, t in d.dtypes.items()}}))
"""


@pytest.mark.parametrize("fast", [True, False])
def test_reader_uses_no_mimalloc_and_keeps_no_arrow_memory(out_csv: Path, tmp_path: Path,
                                                           fast: bool) -> None:
    src = out_csv
    if not fast:  # a Parquet copy: the validating reader
        src = tmp_path / "out.parquet"
        pd.read_csv(out_csv).to_parquet(src)
    pytest.importorskip("pyarrow").mimalloc_memory_pool()
    got = json.loads(subprocess.run([sys.executable, "-c", _PROBE, str(src)], check=True,
                                    capture_output=True, text=True).stdout.splitlines()[-1])
    # (a read through that pool takes its block and columns: hundreds of kB at least).  The
    # Parquet reader of aeromag.io still takes ~0.7 MB from it: the CSV path only.
    took = got["mimalloc_max"]
    assert not fast or took < 65536, f"the read took {took} B of mimalloc"
    assert got["after"] == got["before"], "the default pool was not restored"
    assert got["system_held"] < 4096, "pyarrow memory still held after the read"
    assert all(got["owned"].values()), got["owned"]
    assert got["dtypes"]["segment"] == "int32"
    for c in rep._FLOAT32:
        if c in got["dtypes"]:
            assert got["dtypes"][c] == "float32", c


def test_segment_int32_same_labels_and_wide_ids_stay_int64(out_csv: Path,
                                                           tmp_path: Path) -> None:
    from aeromag.qc import segment_labels

    d = rep.read_columns(out_csv)
    want = pd.read_csv(out_csv)["segment"].to_numpy()
    assert d["segment"].dtype == np.int32
    lab = segment_labels(d)
    assert lab.dtype == np.int64 and np.array_equal(lab, want)
    # ids beyond int32 are kept exactly (int64), by both readers alike
    df = pd.read_csv(out_csv)
    df.loc[df.index[-5:], "segment"] = 2**40
    wide = tmp_path / "wide.csv"
    df.to_csv(wide, index=False)
    fast, slow = rep._read_csv_fast(wide), rep._read_batches(wide)
    assert fast["segment"].dtype == np.int64
    pd.testing.assert_frame_equal(fast, slow, check_exact=True)
    assert np.array_equal(fast["segment"].to_numpy(), df["segment"].to_numpy())
