"""Anderson's mixing: the next point of a fixed-point iteration x → g(x) from its last rounds.

With the rounds' inputs x_i and outputs g_i = g(x_i), residuals f_i = g_i − x_i, and the
differences of the last m + 1 rounds ΔF = [f_i − f_{i−1}], ΔG = [g_i − g_{i−1}] (type II),

    γ = argmin |f_k − ΔF γ|,   x_{k+1} = g_k − ΔG γ,

which is the secant step for m = 1 and exact in one step for a linear g in one dimension. The
norm is the coordinates' own: callers pass coordinates in which one unit means the same in each.
"""

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


def mixed(inputs: npt.ArrayLike, outputs: npt.ArrayLike, depth: int) -> Array:
    """x_{k+1} from the rounds' (k + 1, n) `inputs` and `outputs`, oldest first, mixing the last
    `depth` + 1 of them (module docstring); one round: its output."""
    x = np.asarray(inputs, float)[-depth - 1:]
    g = np.asarray(outputs, float)[-depth - 1:]
    if len(g) < 2:
        return g[-1].copy()
    f = g - x
    gamma = np.linalg.lstsq(np.diff(f, axis=0).T, f[-1], rcond=None)[0]
    return g[-1] - gamma @ np.diff(g, axis=0)
