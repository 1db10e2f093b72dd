"""What a researcher does with run files: per-repetition curves on a common volume grid,
the mean of the last repetitions with its spread, snap-through transitions found in the
measurement, and the comparison with the stability model
(docs/explanation/how-a-run-is-analysed.md).

``analyse_run(path)`` is what the runner calls after finalising a run: it analyses the
file and stores the result in it (``/entry/analysis``, ``/entry/data``);
``summary_text(result)`` is its terminal summary.
"""

from labrig.analysis.analyse import analyse, analyse_run
from labrig.analysis.report import summary_text
from labrig.analysis.results import AnalysisResult

__all__ = ["AnalysisResult", "analyse", "analyse_run", "summary_text"]
