"""A command's start-up runs without the garbage collector walking its imports, and the
collector is on again for what the command does next; a caller that goes on (a test, a
notebook) keeps its collector as it was."""

import gc
import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from labrig.cli import main

DEMO = Path(__file__).parents[2] / "protocols" / "demo.yaml"

# `labrig run demo.yaml --sim --dry-run` as from the shell, each collection recorded:
# whether it came after pydantic's import (the protocol's models: the start-up's largest
# import, scipy being left to tabulating) with nothing frozen, i.e. a pass over the
# start-up's objects
COMMAND = textwrap.dedent(
    """\
    import atexit, gc, json, sys

    passes = []

    def record(phase, info):
        if phase == "stop":
            passes.append([info["generation"], "pydantic" in sys.modules, gc.get_freeze_count()])

    def report():
        print(json.dumps({"passes": passes, "enabled": gc.isenabled()}))

    atexit.register(report)
    import labrig.cli

    gc.callbacks.append(record)
    sys.argv = ["labrig", "run", sys.argv[1], "--sim", "--dry-run"]
    labrig.cli.main()
    """
)


def test_a_commands_imports_are_not_walked_by_the_collector():
    done = subprocess.run(
        [sys.executable, "-c", COMMAND, str(DEMO)], capture_output=True, text=True, check=True
    )
    found = json.loads(done.stdout.strip().splitlines()[-1])
    over_imports = [p for p in found["passes"] if p[1] and p[2] == 0]
    assert over_imports == []
    assert found["enabled"]  # and on for what the command did after its start-up


def test_a_caller_that_goes_on_keeps_its_collector_as_it_was(tmp_path, monkeypatch):
    # the calls, not the frozen count: objects an earlier test froze in this worker (a
    # run freezes what it finds) may be freed meanwhile, and the count falls with them
    freezes = []
    monkeypatch.setattr(gc, "freeze", lambda: freezes.append(1))
    with pytest.raises(SystemExit) as exit_:  # through the command's start-up, to its end
        main(["run", str(tmp_path / "missing.yaml"), "--sim", "--dry-run"])
    assert exit_.value.code == 2
    assert gc.isenabled()
    assert freezes == []
