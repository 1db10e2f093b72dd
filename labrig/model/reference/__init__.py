"""Slow, independent solvers that the fast path is checked against: the paper's
incremental Nelder-Mead algorithm and a dense grid of equilibria."""
