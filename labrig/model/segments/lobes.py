"""The latex between the braids: the lobes the tube pushes out through the gaps.

The eight strips are cut from the braid tubing, so at rest they close its circumference:
each is 1/8 of it wide, w = 2 pi a/8 at the inner face (a = 3.97 mm, the face the latex
tube touches). Bowed out to radius r the strips cover 8 w of the circumference 2 pi r
and leave eight gaps, each the angle alpha = 2 pi/8 - w/r of the circle, with the chord
c = 2 r sin(alpha/2). The tube lies on the strips' inner faces and spans each gap as a
membrane; with no bending stiffness and a hoop tension T the same around the
circumference (the latex slides on the strips), a gap's membrane is a circular arc of
radius rho = T/p (Laplace) over the chord c. Its half-angle phi, sin(phi) = c/(2 rho),
describes it:

- arc length s = c phi/sin(phi);
- area between chord and arc A = (c/(2 sin phi))^2 (phi - sin(phi) cos(phi)).

While the tube presses on nothing, p r = T and the arc is the circle itself (phi =
alpha/2): no lobe. Pressed against the strips, p r > T, the arc is tighter than the
circle and bulges out of it: the lobe. Its volume and its extra arc length are measured
from the circle, so they start at zero at contact.

In the shallow limit (rho and r much larger than c) a lobe's extra area is
c^3/12 (1/rho - 1/r), a parabola's; at fixed chord dA/ds = rho (the virtual work of the
pressure, p dA = T ds).
"""

from __future__ import annotations

import numpy as np

# Paper (main text): "Eight braids are formed by partly cutting this outer tube".
STRIP_COUNT = 8


def strip_width_mm(braid_inner_radius_mm: float) -> float:
    """Width of a strip at its inner face, 2 pi a/8: the eight strips close the tubing's
    inner circumference (a cut by a blade removes no measurable width). A technician
    checks it with calipers across a strip's inner face: the chord 2 a sin(pi/8), 3.04
    mm for a = 3.97 mm, against the arc's 3.12 mm."""
    return 2 * np.pi * braid_inner_radius_mm / STRIP_COUNT


def gap_angle(radius_mm, width_mm: float):
    """The angle of the circle of radius ``radius_mm`` one gap leaves open: 2 pi/8 - w/r
    (zero while the strips still touch)."""
    r = np.asarray(radius_mm, dtype=float)
    return np.maximum(2 * np.pi / STRIP_COUNT - width_mm / r, 0.0)


def chord_mm(radius_mm, width_mm: float):
    """The straight span of one gap, 2 r sin(alpha/2)."""
    r = np.asarray(radius_mm, dtype=float)
    return 2 * r * np.sin(0.5 * gap_angle(r, width_mm))


def arc_length_mm(chord, half_angle):
    """Length of the circular arc of half-angle phi over the chord: c phi/sin(phi)."""
    phi = np.asarray(half_angle, dtype=float)
    return chord * phi / np.sin(phi)


def segment_area_mm2(chord, half_angle):
    """Area between the chord and the arc of half-angle phi:
    (c/(2 sin phi))^2 (phi - sin(phi) cos(phi))."""
    phi = np.asarray(half_angle, dtype=float)
    rho = chord / (2 * np.sin(phi))
    return rho**2 * (phi - np.sin(phi) * np.cos(phi))


def arc_radius_mm(chord, half_angle):
    """The arc's radius c/(2 sin phi): the membrane's T/p."""
    return chord / (2 * np.sin(np.asarray(half_angle, dtype=float)))
