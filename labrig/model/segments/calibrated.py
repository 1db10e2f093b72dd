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
  with a fitted slope to the bulge's Maxwell propagation pressure and stays there until
  the tube lies against the braids.

The values are the result of ``labrig model calibrate`` (``labrig.model.paper.fit``),
fitted to the peak range of the 36 segments and Movie S3 only.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

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
    drop_kpa_per_ml: float

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


# Fitted by `labrig model calibrate` (objective in docs/explanation/calibration.md).
CALIBRATION = Calibration(
    shear_modulus_mpa=0.6302,
    ogden_alpha=1.290,
    end_stiffening=5.010,
    force_scale=0.7699,
    envelope_radius_mm=5.461,
    contact_compliance=1.547,
    drop_kpa_per_ml=357.7,
)


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
    return bulging_curve(uniform, calibration.drop_kpa_per_ml)
