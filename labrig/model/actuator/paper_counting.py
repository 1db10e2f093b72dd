"""Transitions counted as the paper counts them: what happens at one supplied volume.

The path's events (``labrig.model.actuator.transitions``) are fine-grained: a segment
crossing its peak smoothly is one event (a stable change of branch) and the snap at
constant volume that the crossing sets off is another. The paper counts them as one
state transition (main text, "Numerical Results", and Fig. 3D-E: at v = 19 mL "an
unstable (1, 1) transition", where one segment crosses its peak inflating and the other
deflating; at 22 mL "a second instability of type (1, 2)"). Its algorithm steps the
supplied volume and compares the states of consecutive steps, so everything between two
steps is one transition, typed by the segments right of their peak before and after.

Grouping (``group_paper_transitions``): a snap that comes within ``SAME_VOLUME_ML`` of
supplied volume after the event before it (a crossing, or a snap it lands in) belongs to
that event's transition; a crossing always starts a transition of its own, as does
anything after a change of actuator or of direction. So a crossing and the snap it sets
off are one unstable transition, a crossing that sets off nothing stays a stable one,
and two crossings stay two. The tolerance is needed because a smooth peak's falling
side starts flat, so the fold the crossing leads to comes a little further on (0.003-1.0
mL on the calibrated library's 630 pairs), never at exactly the crossing's volume.
``SAME_VOLUME_ML`` is 1.5 mL: on that library the counts of (0, 1), (1, 1) and (1, 2)
are the same for any tolerance from 1.01 to 5 mL, and it is half the 3 mL between the
two instabilities of Fig. 3 (19 and 22 mL), which the paper counts as two
(docs/explanation/scans.md has the counts against the tolerance).

A transition's numbers are:
- ``v_ml``: the supplied volume just before its first event; ``direction`` its events'.
- ``alpha``: the first event's alpha; ``beta``: the last event's beta.
- ``stable``: True only if no event of it is a snap.
- ``dE``, ``dv``, ``dl``, ``dp``: the sums of its events' values. Each event's value is
  relative to its own pre state, and between a crossing and its snap the pump supplies
  up to ``SAME_VOLUME_ML``, whose work is not released by the transition (1 mL at 70 kPa
  is 70 mJ, several per cent of the stored energy: more than many snaps release). The
  sum keeps the changes at the events and leaves out the smooth stretch between them;
  where events chain at one volume it is the change from the first pre to the last post
  to first order. So the sums of dE, dv, dl and dp over a path are the same counted
  either way.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from labrig.model.actuator.transitions import Transition, TransitionNumbers

SAME_VOLUME_ML = 1.5
# the fields of a fine-grained event (a scan file's row, a ``Transition``)
EVENT_FIELDS = ("direction", "v_ml", "alpha", "beta", "stable", "dE", "dv", "dl", "dp")
SUMMED = ("dE", "dv", "dl", "dp")


def group_paper_transitions(
    events: Mapping[str, np.ndarray],
    actuator: np.ndarray | None = None,
    same_volume_ml: float = SAME_VOLUME_ML,
) -> dict[str, np.ndarray]:
    """The paper's transitions made of fine-grained ``events`` (see the module
    docstring), as columns.

    ``events`` maps ``EVENT_FIELDS`` to equal-length arrays in path order (a scan's rows;
    ``actuator``, the actuator of each row, sorted, keeps actuators apart). Returns the
    same fields per transition, plus ``first`` (the row of its first event), ``events``
    (how many events it holds) and, if given, ``actuator``. Pure: the input is not
    changed."""
    v = np.asarray(events["v_ml"], dtype=float)
    direction = np.asarray(events["direction"])
    stable = np.asarray(events["stable"], dtype=bool)
    count = len(v)
    joins = np.zeros(count, dtype=bool)
    if count > 1:
        joins[1:] = (
            ~stable[1:]
            & (direction[1:] == direction[:-1])
            & (np.abs(v[1:] - v[:-1]) <= same_volume_ml)
        )
        if actuator is not None:
            actuator = np.asarray(actuator)
            joins[1:] &= actuator[1:] == actuator[:-1]
    first = np.flatnonzero(~joins)
    last = np.append(first[1:], count)[: len(first)] - 1
    out = {
        "direction": direction[first],
        "v_ml": v[first],
        "alpha": np.asarray(events["alpha"])[first],
        "beta": np.asarray(events["beta"])[last],
        "stable": np.logical_and.reduceat(stable, first) if count else stable[:0],
        "first": first,
        "events": last - first + 1,
    }
    for name in SUMMED:
        values = np.asarray(events[name], dtype=float)
        out[name] = np.add.reduceat(values, first) if count else values[:0]
    if actuator is not None:
        out["actuator"] = actuator[first]
    return out


@dataclass(frozen=True)
class PaperTransition(TransitionNumbers):
    """One transition as the paper counts it (module docstring): its numbers and the
    path's events it is made of, in order."""

    events: tuple  # the ``Transition``s (or the events given) it is made of


def paper_transitions(
    found: Sequence[Transition], same_volume_ml: float = SAME_VOLUME_ML
) -> list[PaperTransition]:
    """``group_paper_transitions`` of one path's transitions (``Transition``s, or any
    events with the ``EVENT_FIELDS`` as attributes), as objects that keep their
    events."""
    columns = {name: np.array([getattr(t, name) for t in found]) for name in EVENT_FIELDS}
    grouped = group_paper_transitions(columns, same_volume_ml=same_volume_ml)
    return [
        PaperTransition(
            v_ml=float(grouped["v_ml"][k]),
            alpha=int(grouped["alpha"][k]),
            beta=int(grouped["beta"][k]),
            stable=bool(grouped["stable"][k]),
            dE=float(grouped["dE"][k]),
            dv=float(grouped["dv"][k]),
            dl=float(grouped["dl"][k]),
            dp=float(grouped["dp"][k]),
            direction=int(grouped["direction"][k]),
            events=tuple(found[start : start + size]),
        )
        for k, (start, size) in enumerate(zip(grouped["first"], grouped["events"], strict=True))
    ]
