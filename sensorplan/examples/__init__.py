"""Embedded example cases (TOML files)."""
