"""The tutorial notebook, executed: by the suite (tests/api/test_tutorial.py) so that it
can never drift from the code, and by hand to store its outputs, which GitHub shows::

    python tests/support/tutorial.py

It runs in a fresh folder (its ``runs/`` are written there, not into the repository)
with the protocol it uses beside it, on this Python's kernel.
"""

from __future__ import annotations

import shutil
import signal
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
NOTEBOOK = REPO / "docs/tutorials/runs-in-a-notebook.ipynb"
PROTOCOL = REPO / "docs/tutorials/quick-demo.yaml"
TIMEOUT_S = 600  # a cell's limit; the whole notebook takes ~20 s


def execute(workdir: Path):
    """The notebook executed top to bottom in ``workdir`` (nbclient raises
    ``CellExecutionError`` at the first cell that fails)."""
    import nbformat
    from nbclient import NotebookClient

    notebook = nbformat.read(NOTEBOOK, as_version=4)
    shutil.copy(PROTOCOL, workdir)
    client = NotebookClient(
        notebook,
        timeout=TIMEOUT_S,
        kernel_name="python3",
        resources={"metadata": {"path": str(workdir)}},
    )
    # the notebook client leaves Python's default Ctrl-C handler where it found another
    # (a test worker's, which ignores it): put back what was there
    handler = signal.getsignal(signal.SIGINT)
    try:
        client.execute()
    finally:
        signal.signal(signal.SIGINT, handler)
    return notebook


def main() -> None:
    import nbformat

    with tempfile.TemporaryDirectory() as workdir:
        notebook = execute(Path(workdir))
    nbformat.write(notebook, NOTEBOOK)
    print(f"rewrote {NOTEBOOK.relative_to(REPO)} with its outputs ({sys.executable})")


if __name__ == "__main__":
    main()
