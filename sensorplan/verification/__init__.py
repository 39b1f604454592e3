"""Verification of layouts by full Bayesian inversion of synthetic damage.

Owns: damage scenarios, truth meshes, scoring, :func:`verify_layouts`,
design studies (:func:`design_study`).
May import: inference, design, io (cases by name or path), model and the foundations.
"""
