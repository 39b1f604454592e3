"""The model layer: what the bridge is and what the sensors would read.

Structure (spans, supports, springs, mesh), loads (vehicles, load sweeps),
sensors, noise, the GMRF prior, the exact force-method kernel (influence
lines and their Jacobians), cases, crossings (data containers), simulation
and the Fisher information of sensors.

Owns: value objects, the forward model, Fisher information.
May import: the foundations (errors, validation, threads) only.
"""
