"""The emulator's built-in syringe table: ``syrm`` picks a syringe by manufacturer code
and volume (setting the diameter and syringe volume together), ``syrmanu`` lists the
manufacturers and their sizes.

A model, not the pump's table: two manufacturers the clients use (``bdp``, BD
Plastipak; ``hm1``, Hamilton 1000 series), with commonly published inner diameters.
The real table is longer; a code it lacks is an argument error here.
"""

from __future__ import annotations

from dataclasses import dataclass

from .pump_refusals import argument_error
from .pump_units import UnitError, read_volume_ml, volume_text

MANUFACTURERS = {"bdp": "BD Plastipak", "hm1": "Hamilton 1000 series"}
# (manufacturer, nominal volume in mL) -> inner diameter in mm
DIAMETERS_MM = {
    ("bdp", 1.0): 4.699,
    ("bdp", 3.0): 8.585,
    ("bdp", 5.0): 11.989,
    ("bdp", 10.0): 14.427,
    ("bdp", 20.0): 19.05,
    ("bdp", 30.0): 21.59,
    ("bdp", 60.0): 26.7,
    ("hm1", 1.0): 4.608,
    ("hm1", 2.5): 7.284,
    ("hm1", 5.0): 10.3,
    ("hm1", 10.0): 14.57,
    ("hm1", 25.0): 23.03,
}


@dataclass(frozen=True)
class SyringeChoice:
    code: str
    volume_ml: float
    diameter_mm: float

    @property
    def text(self) -> str:
        return f"{self.code} {volume_text(self.volume_ml)}"


def choose(arg: str) -> SyringeChoice:
    """``'bdp 60 ml'`` -> the table's syringe (argument error if it has none)."""
    words = arg.split()
    if len(words) != 3 or words[0].lower() not in MANUFACTURERS:
        raise argument_error(arg)
    try:
        volume_ml, _ = read_volume_ml(words[1], words[2])
    except UnitError as exc:
        raise argument_error(exc.text) from None
    code = words[0].lower()
    for (maker, nominal_ml), diameter_mm in DIAMETERS_MM.items():
        if maker == code and abs(nominal_ml - volume_ml) <= 1e-9 * nominal_ml:
            return SyringeChoice(code, nominal_ml, diameter_mm)
    raise argument_error(f"{words[1]} {words[2]}", "Syringe not in table")


def manufacturer_lines(arg: str) -> list[str]:
    """``syrmanu ?``: every manufacturer; ``syrmanu bdp ?``: its sizes."""
    words = arg.lower().split()
    if words == ["?"] or not words:
        return [f"{code}  {name}" for code, name in MANUFACTURERS.items()]
    if len(words) == 2 and words[1] == "?" and words[0] in MANUFACTURERS:
        return [
            f"{volume_text(volume_ml)}  {diameter_mm:.4f} mm"
            for (maker, volume_ml), diameter_mm in DIAMETERS_MM.items()
            if maker == words[0]
        ]
    raise argument_error(arg)
