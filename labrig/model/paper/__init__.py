"""The model against the paper: its statements, checked, and the fit that calibrates the
library on a named subset of them."""
