"""Verification of layouts by full Bayesian inversion of synthetic damage.

Owns: damage scenarios, truth meshes, scoring, :func:`verify_layouts`.
May import: inference, design, model and the foundations.
"""
