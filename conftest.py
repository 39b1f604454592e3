import os

# The package's dense algebra is on small matrices, where multi-threaded BLAS
# only adds overhead (and stalls on a busy machine); the CLI makes the same
# choice (sensorplan.cli._limit_blas_threads).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

# Keep pytest's doctest collection away from the module that runs the CLI on import.
collect_ignore = ["sensorplan/__main__.py"]

# Tests are deterministic: hypothesis draws its examples from a fixed seed.
from hypothesis import settings

settings.register_profile("sensorplan", derandomize=True, deadline=None, print_blob=True)
settings.load_profile("sensorplan")
