"""What a researcher does with run files: per-repetition curves on a common volume grid,
the mean of the last repetitions with its spread, snap-through transitions found in the
measurement, and the comparison with the stability model
(docs/explanation/how-a-run-is-analysed.md).

``analyse_run(path)`` is what the runner calls after finalising a run: it analyses the
file and stores the result in it (``/entry/analysis``, ``/entry/data``);
``summary_text(result)`` is its terminal summary.

The names are imported on first use: the comparison with the model imports the model's
solver, whose mode (compiled or plain Python) that first import fixes for the process,
so reading a run file (``labrig.analysis.runfile``, which the Python API reads through)
must not import it; the API chooses the mode before it analyses
(``labrig.api.solver_mode``).
"""

import sys
import types

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.analysis",
    {
        "analyse": ["analyse", "analyse_run"],
        "report": ["summary_text"],
        "results": ["AnalysisResult"],
    },
)


class _Package(types.ModuleType):
    """This package, whose function ``analyse`` has the name of the module defining it.

    Python sets a package's attribute to each of its modules as it first imports it,
    which would hide the function for good once any code imported the module itself:
    the attribute is left to ``__getattr__``, which gives the function."""

    def __setattr__(self, name: str, value: object) -> None:
        if not (name == "analyse" and isinstance(value, types.ModuleType)):
            super().__setattr__(name, value)


sys.modules[__name__].__class__ = _Package
