"""Slow, independent solvers that the fast path is checked against: the paper's
incremental Nelder-Mead algorithm and a dense grid of equilibria."""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.model.baselines",
    {
        "nelder_mead": ["reference_path"],
    },
)
