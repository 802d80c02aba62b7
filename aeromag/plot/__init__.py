"""Plots (matplotlib, headless): compensation diagnostics and track checks.

Submodules: :mod:`aeromag.plot.compensation` and :mod:`aeromag.plot.track`.
"""
