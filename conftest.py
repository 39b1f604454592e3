# Keep pytest's doctest collection away from the module that runs the CLI on import.
collect_ignore = ["sensorplan/__main__.py"]

# Tests are deterministic: hypothesis draws its examples from a fixed seed.
from hypothesis import settings

settings.register_profile("sensorplan", derandomize=True, deadline=None, print_blob=True)
settings.load_profile("sensorplan")
