"""Transitions counted as the paper counts them: one per supplied volume.

The path's events (``labrig.model.actuator.transitions``) log a peak crossing and the
snap it sets off at the same supplied volume as two transitions, the crossing stable.
The paper's Fig. 4 and its text ("a second instability of type (1, 2)", "(1, 2) can be
either stable or unstable") count what happens at one volume as one transition: typed
(alpha, beta) by the segments right of their peak before the first event and after the
last, unstable if any of them is a snap, with dE, dv, dl, dp from the state before the
first to the state after the last.
"""

from __future__ import annotations

from dataclasses import replace

from labrig.model.actuator.path import INFLATE, Path
from labrig.model.actuator.transitions import Transition, transitions

# events whose supplied volumes agree to this are one transition (the path's volumes are
# exact to about 1e-12 mL; a snap's pre state is the crossing's post state)
SAME_VOLUME_ML = 1e-6


def _merged(actuator, group: list[Transition]) -> Transition:
    first, last = group[0], group[-1]
    pre, post = first.pre, last.post
    e_pre, e_post = actuator.energy_mj(pre.v_i_ml), actuator.energy_mj(post.v_i_ml)
    l_pre, l_post = actuator.length_mm(pre.v_i_ml), actuator.length_mm(post.v_i_ml)
    flow = max(b - a for a, b in zip(pre.v_i_ml, post.v_i_ml, strict=True))
    return replace(
        first,
        beta=last.beta,
        stable=all(t.stable for t in group),
        dE=(e_post - e_pre) / e_pre,
        dv=flow / pre.v_ml,
        dl=(l_post - l_pre) / l_pre,
        dp=(post.p_kpa - pre.p_kpa) / pre.p_kpa,
        post=post,
    )


def paper_transitions(path: Path) -> list[Transition]:
    """The inflation transitions of ``path`` as the paper counts them (module
    docstring), in order."""
    groups: list[list[Transition]] = []
    for t in transitions(path):
        if t.direction != INFLATE:
            continue
        if groups and abs(t.v_ml - groups[-1][-1].v_ml) <= SAME_VOLUME_ML:
            groups[-1].append(t)
        else:
            groups.append([t])
    return [g[0] if len(g) == 1 else _merged(path.actuator, g) for g in groups]
