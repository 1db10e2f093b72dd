"""The error texts an emulated PHD ULTRA answers with, each a payload line and a detail
line, followed by the normal prompt.

The layouts: ``Argument error: [on]`` then ``   Unknown argument`` is quoted by chembot
from a real PHD ULTRA; ``Range error: {value}`` then ``   ... out of range of A to B.``
is the Ultra family manual's (its ``gang`` example); ``Command error: [word]`` with
``   Unknown command`` or the reason the command is not allowed now follows the
argument error's layout (chembot: a command error means unrecognised, wrong mode, or
not possible in the pump's state).
"""

from __future__ import annotations


class Refused(Exception):
    """A command the pump answers with an error text (``lines``)."""

    def __init__(self, *lines: str) -> None:
        super().__init__(lines[0])
        self.lines = list(lines)


def argument_error(arg: str, detail: str = "Unknown argument") -> Refused:
    return Refused(f"Argument error: [{arg}]", f"   {detail}")


def range_error(arg: str, what: str, low: str, high: str) -> Refused:
    return Refused(f"Range error: {arg}", f"   {what} out of range of {low} to {high}.")


def command_error(word: str, detail: str) -> Refused:
    return Refused(f"Command error: [{word}]", f"   {detail}")


def unknown_command(word: str) -> Refused:
    return command_error(word, "Unknown command")


def word_setting(owner: object, attribute: str, arg: str, allowed: tuple[str, ...]) -> list[str]:
    """A setting that is one of a few words: shown capitalised (``Off``) when asked with
    no argument, set (any case) to one of ``allowed``, an argument error otherwise."""
    if not arg:
        return [getattr(owner, attribute).capitalize()]
    if arg.lower() not in allowed:
        raise argument_error(arg)
    setattr(owner, attribute, arg.lower())
    return []
