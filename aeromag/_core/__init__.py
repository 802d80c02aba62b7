"""Pure numerics on arrays: no files, no pandas frames of logs, no domain knowledge.

Everything in :mod:`aeromag._core` may be imported by any layer above it (domain packages,
``plot``, ``workflows``, ``cli``) and imports nothing from them.  Modules: ``runs`` (runs of a
label or mask), ``angles`` (wrapping and circular means), and the numerics of the estimators
(``rls``: recursive least squares with forgetting; ``unscented``: the unscented transform;
``particles``: the particle-filter library).
"""
