"""The sensors' display units: residuals and findings in µrad or mm.

Owns: :data:`UNITS`, :func:`in_unit`.  May import: nothing.
"""

__all__ = ["UNITS", "in_unit"]

UNITS = {"rotation": (1e6, "µrad"), "deflection": (1e3, "mm")}  # sensor kind -> (factor from SI, unit)


def in_unit(value, kind):
    """A residual [rad or m] in the sensor's engineering unit, as text."""
    scale, unit = UNITS[kind]
    return f"{scale * value:.3g} {unit}"
