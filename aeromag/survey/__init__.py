"""The survey chain after compensation: from a compensated log to a levelled anomaly grid.

Geometry (projection, lines and ties), lag, diurnal correction from a base station, IGRF
removal, crossings, tie-line levelling, micro-levelling, minimum-curvature gridding and grid
transforms.  Pure numerics on arrays and typed results (grids as ``xarray.Dataset``); files are
read and written by :mod:`aeromag.workflows`.
"""
