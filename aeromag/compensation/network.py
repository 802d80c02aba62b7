"""The network of ``--estimator mlp``: a small MLP correcting the linear prediction, saved portably.

MagNav.jl's "model 2b": scikit-learn's ``MLPRegressor`` learns what the linear fit (TL terms and
extras, against a reference) leaves, from the same inputs.  Rows are split in time, never
shuffled: the first 60 % train it, the next 20 % stop it early, the last 20 % judge it against
the linear fit alone; it is kept only when it lowers that error.  It is saved as plain arrays
(weights, biases, scaling) and evaluated with numpy (:class:`MLPCorrection`): no pickle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError

__all__ = ["MLPCorrection", "train_mlp"]


@dataclass
class MLPCorrection:
    """A small network correcting the linear prediction, as plain arrays (portable JSON).

    ``correction = out(relu(... relu(((x - x_center) / x_scale) @ W0 + b0) ...)) * y_scale``
    with ``x`` the TL terms (design-matrix columns) then the extras.

    Attributes
    ----------
    weights, biases : list of ndarray
        Layer weights (in, out) and biases (out,), as scikit-learn's ``coefs_`` /
        ``intercepts_``.
    x_center, x_scale : ndarray
        Standardisation of the inputs.
    y_scale : float
        Scale of the output [nT].
    """

    weights: list[np.ndarray]
    biases: list[np.ndarray]
    x_center: np.ndarray
    x_scale: np.ndarray
    y_scale: float

    def predict(self, X: np.ndarray) -> np.ndarray:
        """The correction [nT] for inputs ``X`` (n, k); NaN rows give NaN."""
        h = (np.asarray(X, dtype=np.float64) - self.x_center) / self.x_scale
        for i, (W, c) in enumerate(zip(self.weights, self.biases, strict=True)):
            h = h @ W + c
            if i < len(self.weights) - 1:
                np.maximum(h, 0.0, out=h)
        return h[:, 0] * self.y_scale

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready arrays."""
        return {"activation": "relu", "weights": [w.tolist() for w in self.weights],
                "biases": [c.tolist() for c in self.biases],
                "x_center": self.x_center.tolist(), "x_scale": self.x_scale.tolist(),
                "y_scale": float(self.y_scale)}

    @classmethod
    def from_dict(cls, d: dict[str, Any], n_inputs: int, source: str) -> MLPCorrection:
        """Read and check the arrays written by :meth:`to_dict`."""
        bad = InputError(f"{source}: the model's network (extended.mlp) is malformed; write "
                         "the model again with 'aeromag calibrate'")
        try:
            W = [np.asarray(w, dtype=np.float64) for w in d["weights"]]
            c = [np.asarray(x, dtype=np.float64) for x in d["biases"]]
            xc = np.asarray(d["x_center"], dtype=np.float64)
            xs = np.asarray(d["x_scale"], dtype=np.float64)
            ys = float(d["y_scale"])
        except (KeyError, TypeError, ValueError, OverflowError):
            raise bad from None
        if d.get("activation", "relu") != "relu" or not W or len(W) != len(c):
            raise bad
        width = n_inputs
        for w, bias in zip(W, c, strict=True):
            if w.ndim != 2 or w.shape[0] != width or bias.shape != (w.shape[1],):
                raise bad
            width = w.shape[1]
        if width != 1 or xc.shape != (n_inputs,) or xs.shape != (n_inputs,):
            raise bad
        if not all(np.isfinite(a).all() for a in [*W, *c, xc, xs]) or not np.isfinite(ys):
            raise bad
        return cls(W, c, xc, np.where(xs > 0, xs, 1.0), ys)


def train_mlp(X: np.ndarray, y: np.ndarray, *, seed: int = 0, hidden: tuple[int, ...] = (16,),
              max_epochs: int = 200, patience: int = 10, max_rows: int = 200_000,
              ) -> tuple[MLPCorrection | None, dict[str, Any]]:
    """Train the correction on rows in time order; keep it only if it helps on held-out time.

    The rows are split in time: the first 60 % train, the next 20 % stop the training early
    (the epoch with the lowest validation error is kept), the last 20 % judge it, unseen.

    Parameters
    ----------
    X : ndarray, shape (n, k)
        Inputs (TL terms and extras), rows in time order.
    y : ndarray, shape (n,)
        What the linear fit leaves [nT].
    seed : int
        Seed of the network's initialisation and batches.
    hidden : tuple of int
        Hidden layer widths.
    max_epochs, patience : int
        Most epochs; epochs without a better validation error before stopping.
    max_rows : int
        Training rows used at most (evenly subsampled).

    Returns
    -------
    network : MLPCorrection or None
        None when it does not lower the held-out error.
    record : dict
        ``linear_std_nT`` and ``mlp_std_nT`` on the last 20 %, ``epochs``, ``kept``.
    """
    from sklearn.neural_network import MLPRegressor

    n = len(y)
    a, b = int(0.6 * n), int(0.8 * n)
    if n < 500:
        return None, {"kept": False, "reason": "too few rows to train and judge a network"}
    step = max(1, a // max_rows)
    xc = X[:a].mean(axis=0)
    xs = X[:a].std(axis=0)
    xs = np.where(xs > 0, xs, 1.0)
    ys = float(np.std(y[:a])) or 1.0
    Z = (X - xc) / xs
    net = MLPRegressor(hidden_layer_sizes=hidden, random_state=seed, learning_rate_init=1e-3,
                       alpha=1e-4, batch_size=256)
    best, best_err, wait, epochs = None, np.inf, 0, 0
    rng = np.random.default_rng(seed)
    train = np.arange(0, a, step)
    while epochs < max_epochs:
        epochs += 1
        batch = rng.permutation(train)  # rows and targets shuffled together
        net.partial_fit(Z[batch], y[batch] / ys)
        err = float(np.mean((net.predict(Z[a:b]) - y[a:b] / ys) ** 2))
        if err < best_err:
            best_err, wait = err, 0
            best = ([w.copy() for w in net.coefs_], [c.copy() for c in net.intercepts_])
        else:
            wait += 1
            if wait >= patience:
                break
    assert best is not None
    mlp = MLPCorrection(best[0], best[1], xc, xs, ys)
    lin = float(np.std(y[b:]))
    corr = float(np.std(y[b:] - mlp.predict(X[b:])))
    kept = corr < 0.99 * lin
    record = {"kept": bool(kept), "linear_std_nT": lin, "mlp_std_nT": corr, "epochs": epochs,
              "split": "time order: first 60 % train, next 20 % early stopping, last 20 % judge",
              "hidden": list(hidden), "seed": int(seed)}
    return (mlp if kept else None), record
