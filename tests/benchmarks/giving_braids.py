"""The paper-numbers segments past the fill with braids that give: the single-segment
numbers of decision record 0010.

Run: python tests/benchmarks/giving_braids.py

For each of the 36 ``paper:`` segments, past the fill (or first contact) the branch of
record 0008 (``LobeBranch``) is built three times, differing only in the force the braids
exert once the latex touches them: S31's constant F (record 0008's form), S30's exact F
theta/sin(theta) at the contact angle (the strut at its angle, slightly above S31), and
none at all (a cage that gives completely: the strips follow the tube, the bound of what
giving braids can do in this geometry). Printed per segment: whether it bulges, the
pressure at which the strips start to open, the secant slope from 60 to 75 kPa on the
last rising branch (where a second segment crosses its peak in a pair), and the
Laplace pressure T/r of the tube filling the envelope at the fill, against the plateau.
Everything before the fill (the peaks) is the same in the three.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from labrig.model.segments import lobes
from labrig.model.segments.catalog import library_segment
from labrig.model.segments.lobe_branch import LobeBranch

BAND_KPA = (60.0, 75.0)


class _BraidForce:
    """The segment with the braids' force replaced past the fill (everything else is
    the segment's own)."""

    def __init__(self, segment, force_n: float):
        self._segment, self.axial_force_n = segment, force_n

    def __getattr__(self, name):
        return getattr(self._segment, name)


def _up_crossing_ml(v, p, level):
    """The volume of the last upward crossing of ``level`` (None if there is none)."""
    k = np.flatnonzero((p[:-1] < level) & (p[1:] >= level))
    if not len(k):
        return None
    k = k[-1]
    return v[k] + (level - p[k]) * (v[k + 1] - v[k]) / (p[k + 1] - p[k])


def band_slope(v, p) -> float | None:
    low, high = (_up_crossing_ml(v, p, level) for level in BAND_KPA)
    if low is None or high is None or high <= low:
        return None
    return (BAND_KPA[1] - BAND_KPA[0]) / (high - low)


def opening_kpa(branch: LobeBranch) -> float | None:
    """The pressure at which the strips leave the start angle (None: held to the end)."""
    phi = np.linspace(branch.start_half_angle, branch.end_half_angle, 400)
    theta = branch.braid_angle(phi)
    moved = np.flatnonzero(theta > branch.start_angle + 1e-9)
    if not len(moved):
        return None
    k = moved[0]
    return float(np.atleast_1d(branch.state(theta[k : k + 1], phi[k : k + 1])[1])[0])


def laplace_kpa(branch: LobeBranch) -> float:
    """T/r of the tube on the envelope at the start (the circle through the strips)."""
    segment = branch.segment
    env = branch.envelope(branch.start_angle)
    circle = 0.5 * lobes.gap_angle(env.radius_mm, branch.width_mm)
    hoop, axial, _, _ = branch.stretches(env, circle)
    tension = segment.shear_modulus_mpa * segment.thickness_mm * (hoop - 1 / (hoop**3 * axial**2))
    return float(1e3 * tension / axial / env.radius_mm)


def measure(name: str) -> dict:
    segment = library_segment(f"paper:{name}")
    held = segment.lobes
    curve = segment.curve()
    before = np.asarray(curve.v_ml) < float(held.table[0][0]) - 1e-12
    force = segment.axial_force_n
    theta = held.start_angle
    exact = force * (theta / np.sin(theta) if theta > 0 else 1.0)
    row = {"name": name, "bulge": segment.bulge is not None, "start": held.start_kpa}
    row["laplace"] = laplace_kpa(held)
    for key, f in (("F", force), ("S30", exact), ("none", 0.0)):
        branch = LobeBranch(_BraidForce(segment, f), theta, held.start_kpa)
        v_b, p_b, _ = branch.table
        v = np.concatenate([np.asarray(curve.v_ml)[before], v_b])
        p = np.concatenate([np.asarray(curve.p_kpa)[before], p_b])
        row[key] = (opening_kpa(branch), band_slope(v, p), float(p_b[0]))
    return row


def _kpa(x) -> str:
    return "held" if x is None else f"{x:.1f}"


def main() -> None:
    names = [f"B{b}-T{t}" for b in range(40, 51, 2) for t in range(20, 31, 2)]
    print("segment bulge | start kPa, T/r kPa | open kPa, slope 60-75 kPa/mL: F / S30 / none")
    rows = [measure(n) for n in names]
    for r in rows:
        cells = " / ".join(f"{_kpa(r[k][0])}, {_kpa(r[k][1])}" for k in ("F", "S30", "none"))
        bulge = "yes" if r["bulge"] else "no "
        print(f"{r['name']} {bulge} | {r['start']:.1f}, {r['laplace']:.1f} | {cells}")
    for key in ("F", "S30", "none"):
        bulged = [r for r in rows if r["bulge"]]
        opens = [r[key][0] for r in bulged if r[key][0] is not None]
        walls = [r[key][1] for r in bulged if r[key][1] is not None and r[key][1] > 12.0]
        print(
            f"{key}: bulged 23: strips open at {min(opens):.1f}-{max(opens):.1f} kPa "
            f"({23 - len(opens)} held to the end); slope 60-75 kPa above 12 kPa/mL in "
            f"{len(walls)}, {min(walls):.1f}-{max(walls):.1f} kPa/mL"
        )


if __name__ == "__main__":
    main()
