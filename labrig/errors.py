"""Exceptions that reach a person, each with a message that says what to do.

``LabrigError`` and its subclasses are what the CLI turns into one clear line and a
non-zero exit code; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations


class LabrigError(Exception):
    """Base of every error labrig reports to a person. ``exit_code`` is the CLI's."""

    exit_code = 1


class InputError(LabrigError):
    """Bad input from a person: a file, a key, a value, a name. Nothing was changed."""

    exit_code = 2


class DeviceError(LabrigError):
    """An instrument did not do what it was asked, or could not be reached."""

    exit_code = 3


class LinkLost(DeviceError):
    """A device's link dropped while in use (a cable pulled, a USB device that
    re-enumerated): what the device does is unknown until it is reached again.
    ``lost`` says what was lost, ``unknown`` what that leaves unknown; once a later
    stop of the device is confirmed, ``found_again`` replaces ``unknown``."""

    found_again = "the device was found again and stopped"

    def __init__(self, lost: str, unknown: str = "") -> None:
        super().__init__(f"{lost}; {unknown}" if unknown else lost)
        self.lost = lost
