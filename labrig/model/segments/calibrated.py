"""The calibrated braided segments: the library's default names (``B46-T20``).

The SI's segment (``labrig.model.segments.braided``, under ``SI-B46-T20``) peaks at
38-40 kPa where the paper measured 65-85 kPa, and its peak does not depend on L_tube.
The calibrated form keeps the SI's mechanics and changes what the paper leaves free or
names as the model's limits (docs/explanation/calibration.md):

- the membrane is a one-term Ogden solid (``ogden_braided``; exponent 2 is the SI's
  neo-Hookean latex), which softens more after the peak;
- the shear modulus is fitted, and stiffened at the clamped ends of short tubes as
  mu (1 + c (R / L_tube)^2): a tube clamped at both couplings bulges like a barrel, and
  the meridional curvature of a bulge of length ~L_tube carries a share of the pressure
  that grows like (R / L_tube)^2 (the SI names these boundary conditions as its main
  limit);
- the braid force is the SI's F = 20.4 - 0.281 L_braid (S31, S32) times a fitted factor;
- the braids' envelope has the radius of the braid tubing at its ends, a fitted value
  between the latex's 6.35 mm and the braid tubing's 7.94 mm;
- the braids give way after contact (``contact_compliance``): the stiffening is spread
  over a fitted multiple of the rigid braids' volume;
- past its peak the tube bulges (``labrig.model.segments.bulge``): the pressure drops
  over a fitted width to a plateau a fitted multiple of Maxwell's depth below the peak
  and stays there until the tube lies against the braids;
- the braids themselves give radially after contact (``braid_stiffness``), with an
  assumed stiffness, so that no branch is a wall.

The values are the result of ``labrig model calibrate`` (``labrig.paper.fit``),
fitted to the peak range of the 36 segments and Movie S3 only.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

from labrig.model.segments.braid_stiffness import with_braid_stiffness
from labrig.model.segments.braided import R_TUBE_MM, braid_force_n
from labrig.model.segments.bulge import bulging_curve
from labrig.model.segments.curve import SegmentCurve
from labrig.model.segments.ogden_braided import OgdenBraidedSegment


@dataclass(frozen=True)
class Calibration:
    """The free constants of the calibrated segment (units in the names)."""

    shear_modulus_mpa: float
    ogden_alpha: float
    end_stiffening: float
    force_scale: float
    envelope_radius_mm: float
    contact_compliance: float
    depth_gain: float
    drop_width_ml: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


# Fitted by `labrig model calibrate` (objective in docs/explanation/calibration.md).
CALIBRATION = Calibration(
    shear_modulus_mpa=0.6269,
    ogden_alpha=1.329,
    end_stiffening=5.003,
    force_scale=0.7018,
    envelope_radius_mm=5.241,
    contact_compliance=1.567,
    depth_gain=4.514,
    drop_width_ml=1.527,
)

# Assumed, not fitted: the braids' radial stiffness after contact (a few times the
# stiffening branch's slope, so that it softens the wall and little else).
BRAID_STIFFNESS_KPA_PER_ML = 200.0


def calibrated_segment(
    l_braid_mm: float, l_tube_mm: float, calibration: Calibration = CALIBRATION
) -> OgdenBraidedSegment:
    """The calibrated segment of the given braid and tube lengths."""
    modulus = calibration.shear_modulus_mpa * (
        1 + calibration.end_stiffening * (R_TUBE_MM / l_tube_mm) ** 2
    )
    return OgdenBraidedSegment(
        l_braid_mm,
        l_tube_mm,
        shear_modulus_mpa=modulus,
        force_n=calibration.force_scale * braid_force_n(l_braid_mm),
        envelope_radius_mm=calibration.envelope_radius_mm,
        ogden_alpha=calibration.ogden_alpha,
        contact_compliance=calibration.contact_compliance,
    )


def calibrated_curve(
    l_braid_mm: float, l_tube_mm: float, name: str, calibration: Calibration = CALIBRATION
) -> SegmentCurve:
    """The calibrated segment's p(v), l(v): the uniform tube's curve with its bulge."""
    uniform = calibrated_segment(l_braid_mm, l_tube_mm, calibration).curve(name)
    bulged = bulging_curve(uniform, calibration.depth_gain, calibration.drop_width_ml)
    return with_braid_stiffness(bulged, BRAID_STIFFNESS_KPA_PER_ML)
