"""The real Munich UniBw INC01 inclinometer records, converted by stating their unit and time base only.

Degrees -> rad (x pi / 180) and ISO timestamps -> seconds from the first sample: nothing else is
done to the values (no filtering, no burst removal).  Until the logger units land in
io/logger.py (issue #36), the tests and the crossings study read the records here.
Data: ../shared/realdata/munich_unibw_testbridge_sample (see its SOURCE.md).
"""

import datetime
import io
import pathlib
import zipfile

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = next((p / "shared/realdata/munich_unibw_testbridge_sample" for p in (ROOT.parent, ROOT.parent.parent)
             if (p / "shared/realdata/munich_unibw_testbridge_sample").is_dir()),
            ROOT.parent / "shared/realdata/munich_unibw_testbridge_sample")
FILES = {"reference": ("ReferenceStateINCAt100Hz.csv.zip", "INC-01 [deg]"),
         "support_load": ("UniBw_2022-04-11_ref_support_load_01AllM100Hz.csv.zip", "INC01 [deg]")}


def available():
    return all((DATA / f).is_file() for f, _ in FILES.values())


def munich_inc01(name):
    """(time [s], INC01 [rad]) of the record ``name`` ("reference" or "support_load")."""
    file, column = FILES[name]
    with zipfile.ZipFile(DATA / file) as z:
        text = z.read(z.namelist()[0]).decode()
    rows = text.splitlines()
    header = rows[0].split(",")
    col = header.index(column)
    stamps, values = [], []
    for row in rows[1:]:
        parts = row.split(",")
        stamps.append(datetime.datetime.fromisoformat(parts[0]).timestamp())
        values.append(float(parts[col]))
    time = np.array(stamps) - stamps[0]
    return time, np.deg2rad(np.array(values))
