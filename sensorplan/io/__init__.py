"""Files: case TOML, crossings CSV, all-or-nothing output.

Owns: reading and validating inputs, writing outputs atomically.
May import: model and the foundations.
"""
