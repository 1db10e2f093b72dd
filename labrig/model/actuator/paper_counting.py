"""Transitions counted as the paper counts them: what happens at one supplied volume.

The path's events (``labrig.model.actuator.transitions``) are fine-grained: a segment
crossing its peak smoothly is one event (a stable change of branch) and the snap at
constant volume that the crossing sets off is another. The paper counts them as one
state transition (main text, "Numerical Results", and Fig. 3D-E: at v = 19 mL "an
unstable (1, 1) transition", where one segment crosses its peak inflating and the other
deflating; at 22 mL "a second instability of type (1, 2)"). Its algorithm steps the
supplied volume and compares the states of consecutive steps, so everything between two
steps is one transition, typed by the segments right of their peak before and after.

Grouping (``group_paper_transitions``): events of one actuator and one direction at the
same supplied volume (within ``SAME_VOLUME_ML``, rounding) are one transition: a
crossing that sets off a snap at its own volume, a snap that lands past another fold
and snaps again. Events at two volumes are two transitions, however close: the paper's
algorithm compares the states of consecutive volumes, and a fold a smooth peak's
crossing leads to comes a little further on (0.002-1.0 mL on the calibrated library's
630 pairs), where the supplied volume has changed. So a crossing that sets off a snap
further on is a stable transition and the snap another, typed by its own states (a
(2, 1) or a (2, 2) where the crossing made it so). ``SAME_VOLUME_ML`` is 1e-6 mL: far
below the smallest gap between two events of that library (0.002 mL), far above the
rounding of the volumes at which a cascade's snaps start (docs/explanation/scans.md has
the counts).

A transition's numbers are:
- ``v_ml``: the supplied volume just before its first event; ``direction`` its events'.
- ``alpha``: the first event's alpha; ``beta``: the last event's beta.
- ``stable``: True only if no event of it is a snap.
- ``dE``, ``dl``, ``dp``: its events' relative changes compounded, (1 + a)(1 + b) - 1:
  each is relative to its own pre state, which is the post state of the event before it
  at the same volume, so the compound is the change from the first pre to the last post.
- ``dv``: the sum of its events' flows, each a fraction of the same supplied volume: the
  largest gain of a segment over the whole transition where one segment gains in each
  (a cascade of snaps into it), at most that otherwise.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from labrig.model.actuator.transitions import Transition, TransitionNumbers

SAME_VOLUME_ML = 1e-6
# the fields of a fine-grained event (a scan file's row, a ``Transition``)
EVENT_FIELDS = ("direction", "v_ml", "alpha", "beta", "stable", "dE", "dv", "dl", "dp")
COMPOUNDED = ("dE", "dl", "dp")
SUMMED = ("dv",)


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
        joins[1:] = (direction[1:] == direction[:-1]) & (np.abs(v[1:] - v[:-1]) <= same_volume_ml)
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
    for name in COMPOUNDED:
        values = np.asarray(events[name], dtype=float)
        # through log1p: a transition of one event keeps its value to the last digit
        out[name] = np.expm1(np.add.reduceat(np.log1p(values), first)) if count else values[:0]
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
