"""The ``labrig`` command line.

Sub-commands live in their own modules and are imported only when used, so that
``labrig --help`` answers at once and a missing optional device library cannot break
unrelated commands. A ``LabrigError`` becomes one clear line on stderr and its exit code
(2 for bad input), never a traceback; so does an operating-system error about a named
path (exit code 2); any other exception (a bug) too, as one line with exit code 1.
``labrig --debug COMMAND`` shows the traceback instead.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import importlib
import os
import sys

import click

import labrig
from labrig.errors import LabrigError

# name -> "module:attribute" of a click command or group. Only what is built is listed:
# the CLI never shows a command that would pretend.
COMMANDS: dict[str, tuple[str, str]] = {
    "bench": ("labrig.cli.benchmark", "bench"),
    "compare": ("labrig.cli.review", "compare_command"),
    "export": ("labrig.cli.review", "export"),
    "frames": ("labrig.cli.frames", "frames"),
    "library": ("labrig.cli.library", "library"),
    "model": ("labrig.cli.model", "model"),
    "plot": ("labrig.cli.review", "plot"),
    "protocol": ("labrig.cli.protocol", "protocol"),
    "pump": ("labrig.cli.pump", "pump"),
    "recover": ("labrig.cli.review", "recover"),
    "rig": ("labrig.cli.rig", "rig"),
    "run": ("labrig.cli.run", "run"),
    "runs": ("labrig.cli.runs", "runs"),
    "show": ("labrig.cli.review", "show"),
    "track": ("labrig.cli.track", "track"),
    "watch": ("labrig.cli.watch", "watch"),
}


class LazyGroup(click.Group):
    """A click group whose sub-commands are imported on first use.

    ``lazy_commands`` maps a name to ("module", "attribute"); sub-groups use the same
    class with their own mapping.
    """

    def __init__(self, *args, lazy_commands: dict[str, tuple[str, str]], **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.lazy_commands = lazy_commands

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted([*super().list_commands(ctx), *self.lazy_commands])

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name in self.lazy_commands:
            module_name, attribute = self.lazy_commands[cmd_name]
            with start_up_uncollected():
                module = importlib.import_module(module_name)
            return getattr(module, attribute)
        return super().get_command(ctx, cmd_name)


@click.group(
    cls=LazyGroup,
    lazy_commands=COMMANDS,
    context_settings={"help_option_names": ["-h", "--help"]},
)
@click.version_option(labrig.__version__, prog_name="labrig")
@click.option(
    "--debug", is_flag=True, help="Show the full traceback of an error instead of one line."
)
def cli(debug: bool) -> None:
    """labrig: run inflation protocols on a soft-actuator rig (real or simulated),
    store them in HDF5, and compare them with the snap-through stability model."""
    _SETTINGS["debug"] = debug


# whole_process: the process is the command (run from the shell), and ends with it
_SETTINGS = {"debug": False, "whole_process": False}


@contextlib.contextmanager
def start_up_uncollected():
    """A command's start-up (its imports: a few hundred thousand objects that live to
    the process's end) without the garbage collector's passes over them, about a
    twentieth of the simulated demo's start-up; at the end they are frozen
    (``gc.freeze``), out of every later pass's walk, and the collector is on again for
    what the command does next. A run's collections see what they saw before: the run
    freezes what it finds at its start anyway (``labrig.run.runner``).

    Only in a process that is the command: frozen objects are never collected, which a
    caller that goes on (a test, a notebook) must not have done to its own."""
    if not (_SETTINGS["whole_process"] and gc.isenabled()):
        yield
        return
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        gc.enable()


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return text[0] if text else type(exc).__name__


# Commands that solve many actuators: thousands of calls of the solver's inner loops,
# 20 times faster compiled (labrig.model.actuator.jit); a scan then chooses for itself
# whether compiling pays (labrig.model.scan.plan: a small one on a fresh install runs as
# plain Python). Every other command solves one actuator or none (a run's dry-run
# prediction and analysis, model path/curve, compare, plot, library add): a few hundred
# calls, faster as plain Python than loading the machine code (~0.5 s with numba's
# import) or, on a fresh install, compiling it (~40 s of CPU).
_MANY_ACTUATORS = (("model", "scan"), ("bench",))


def _solves_one_actuator(args: list[str]) -> bool:
    words = tuple(a for a in args if not a.startswith("-"))  # past `labrig --debug`
    return not any(words[: len(c)] == c for c in _MANY_ACTUATORS)


def main(argv: list[str] | None = None) -> None:
    """Console entry point: run the CLI, turning labrig's own errors into one line.

    Run as the console script (``argv`` None), it chooses how the model's inner loops
    run before anything imports them: see ``_MANY_ACTUATORS``. Called with ``argv`` (by
    tests, in a process that may hold the compiled model already) it leaves that alone.
    """
    if argv is None and _solves_one_actuator(sys.argv[1:]):
        os.environ.setdefault("LABRIG_JIT", "python")
    if argv is None:
        _SETTINGS["whole_process"] = True
        # the process ends with the command: the interpreter's collections at exit would
        # walk every object left (after a simulated run, ~0.3 s of a busy machine) only
        # to free memory that the process gives back whole
        atexit.register(gc.freeze)
    try:
        result = cli.main(args=argv, prog_name="labrig", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except LabrigError as exc:
        if _SETTINGS["debug"]:
            raise
        click.echo(f"error: {_one_line(exc)}", err=True)
        sys.exit(exc.exit_code)
    except Exception as exc:
        if _SETTINGS["debug"]:
            raise
        if isinstance(exc, OSError) and exc.filename is not None:
            # the operating system refused a path a person gave (a name too long, a
            # folder that is a file, no permission): about that path, not a bug
            click.echo(f"error: {exc.filename}: {exc.strerror or _one_line(exc)}", err=True)
            sys.exit(2)
        click.echo(
            f"error: internal error ({type(exc).__name__}: {_one_line(exc)}); "
            "labrig --debug ... shows the traceback",
            err=True,
        )
        sys.exit(1)
    sys.exit(result if isinstance(result, int) else 0)
