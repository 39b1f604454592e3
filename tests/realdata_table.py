"""The openLAB PE 2.1 plateau table shipped in studies/realdata/derived/, as the study's plateau objects.

The table (CC BY-SA 4.0; Herbers, Richter, Walker, Marx, TU Dresden,
DOI 10.25532/OPARA-852; see studies/realdata/derived/README.md) is what
``openlab_pe21.write_table`` wrote from the raw catman files.  Reading it
back gives the real-data tests their input on a fresh clone, where the raw
files (``../shared/realdata/openlab_pe21_static_loadtest``) are absent.
"""

import csv

import numpy as np


def plateaus_from_table(pe21, path=None):
    """The rows of the derived table as ``pe21.StepPlateau`` objects (SI units).

    ``end`` (the reading after unloading, on the file's own zero) is not a
    column; it is baseline + residual, as the reader defines the residual.
    """
    with open(pe21.TABLE if path is None else path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert list(rows[0]) == list(pe21.COLUMNS), "the derived table's columns changed"
    out = []
    for r in rows:
        def lasers(suffix, r=r):
            return np.array([float(r[f"{ch}{suffix}"]) for ch in pe21.LASERS])

        baseline, residual = lasers("_baseline_m"), lasers("_residual_m")
        out.append(pe21.StepPlateau(
            step=int(r["step"]), file=r["file"], u_max=float(r["u_max_m"]), tared=bool(int(r["tared"])),
            dt=float(r["dt_s"]), t_start=float(r["t_start_s"]), t_end=float(r["t_end_s"]),
            n_samples=int(r["n_samples"]), force=float(r["force_N"]), force_noise=float(r["force_noise_N"]),
            force_baseline=float(r["force_baseline_N"]), deflection=lasers("_m"), noise=lasers("_noise_m"),
            baseline=baseline, offset=lasers("_offset_m"), residual=residual, end=baseline + residual,
            n_spikes=int(r["LWA_4_spikes_removed"])))
    return tuple(out)
