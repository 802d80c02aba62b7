"""Simulators with ground truth.  They never import the fitting or filtering code, so they
are true oracles for the tests."""
