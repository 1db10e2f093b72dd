"""Numbers and units as an emulated PHD ULTRA reads and prints them.

Reading: every spelling the Ultra command set takes for a volume (``ml``, ``ul``,
``nl``, ``pl`` and their one-letter forms ``m``, ``u``, ``n``, ``p``, as flowchem sends
``10 m`` and ``0.5 m/m``) and for a rate's time base (``min``/``m``, ``hr``/``h``,
``sec``/``s``), in any case. Printing: what real pumps are quoted to print, the unit
always spelled out in lower case ASCII (``ml``, ``ul``, ``ml/min``, ``ul/hr``): up to six
significant digits with trailing zeros dropped (``60 ml``, ``10 ml/min``,
``15.3477 ml/min``, ``14.7792 nl/min``), the volume unit scaled so the number is at
least 1, and the diameter with four decimals (``9.5250 mm``).

Written independently of the driver's protocol module on purpose: a shared unit table
would hide a unit error from every test.
"""

from __future__ import annotations

import math

# volume units to mL, largest first (the order the printer scales through)
VOLUME_ML = {"ml": 1.0, "ul": 1e-3, "nl": 1e-6, "pl": 1e-9}
_VOLUME_SPELLINGS = {
    **{unit: unit for unit in VOLUME_ML},
    "m": "ml",
    "u": "ul",
    "n": "nl",
    "p": "pl",
}
# time bases to minutes, with the spelling the pump prints
TIME_MIN = {"min": 1.0, "hr": 60.0, "sec": 1 / 60}
_TIME_SPELLINGS = {
    **{unit: unit for unit in TIME_MIN},
    "m": "min",
    "h": "hr",
    "s": "sec",
}
SIGNIFICANT_DIGITS = 6


class UnitError(ValueError):
    """A unit or number the pump does not read (``text`` is what it did not read)."""

    def __init__(self, text: str) -> None:
        super().__init__(text)
        self.text = text


def read_number(text: str) -> float:
    """A finite decimal number, as typed after a command."""
    try:
        value = float(text)
    except ValueError:
        raise UnitError(text) from None
    if not math.isfinite(value):
        raise UnitError(text)
    return value


def read_volume_unit(text: str) -> str:
    """``'m'``, ``'ML'``, ``'ul'`` -> the canonical spelling (``'ml'``, ``'ul'``)."""
    unit = _VOLUME_SPELLINGS.get(text.lower())
    if unit is None:
        raise UnitError(text)
    return unit


def read_rate_unit(text: str) -> tuple[str, str]:
    """``'m/m'``, ``'ul/h'``, ``'ML/MIN'`` -> (volume unit, time base), canonical."""
    volume, slash, time_base = text.lower().partition("/")
    if not slash or time_base not in _TIME_SPELLINGS or volume not in _VOLUME_SPELLINGS:
        raise UnitError(text)
    return _VOLUME_SPELLINGS[volume], _TIME_SPELLINGS[time_base]


def read_volume_ml(value: str, unit: str) -> tuple[float, str]:
    canonical = read_volume_unit(unit)
    return read_number(value) * VOLUME_ML[canonical], canonical


def read_rate_ml_min(value: str, unit: str) -> tuple[float, str]:
    """(rate in mL/min, the time base it was given in)."""
    volume, time_base = read_rate_unit(unit)
    return read_number(value) * VOLUME_ML[volume] / TIME_MIN[time_base], time_base


def number_text(value: float) -> str:
    """Six significant digits, trailing zeros and a trailing point dropped: 60 -> '60',
    15.34771 -> '15.3477', 1.5e-5 -> '0.000015'."""
    if value == 0:
        return "0"
    decimals = max(0, SIGNIFICANT_DIGITS - 1 - math.floor(math.log10(abs(value))))
    text = f"{value:.{decimals}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def volume_text(volume_ml: float) -> str:
    """A volume in the largest unit that keeps the number at least 1; an empty counter
    is '0 ul', as real pumps print it."""
    if volume_ml == 0:
        return "0 ul"
    return _scaled(volume_ml, "")


def rate_text(rate_ml_min: float, time_base: str = "min") -> str:
    """A rate in its time base, the volume unit scaled: '15.3477 ml/min', '250 ul/hr';
    a standing motor is '0 ul/min' (as an empty counter is '0 ul')."""
    if rate_ml_min == 0:
        return f"0 ul/{time_base}"
    return _scaled(rate_ml_min * TIME_MIN[time_base], f"/{time_base}")


def _scaled(value_ml: float, suffix: str) -> str:
    units = list(VOLUME_ML.items())
    i = next((k for k, (_, factor) in enumerate(units) if abs(value_ml) >= factor), len(units) - 1)
    # a value that rounds up to 1000 of its unit is printed in the next larger one
    if i > 0 and abs(float(number_text(value_ml / units[i][1]))) >= 1000:
        i -= 1
    unit, factor = units[i]
    return f"{number_text(value_ml / factor)} {unit}{suffix}"


def diameter_text(diameter_mm: float) -> str:
    return f"{diameter_mm:.4f} mm"


def clock_text(seconds: float) -> str:
    """A time as the pump shows a counter or target past a minute: 'hh:mm:ss'; below
    a minute 'N seconds'."""
    whole = round(seconds)
    if whole < 60:
        return f"{whole} seconds"
    return f"{whole // 3600:02d}:{whole % 3600 // 60:02d}:{whole % 60:02d}"


def read_duration_s(text: str) -> float:
    """``'100'`` (seconds), ``'1:40'``, ``'00:01:40'`` -> seconds."""
    parts = text.split(":")
    if len(parts) > 3 or not all(part.strip().isdigit() for part in parts):
        raise UnitError(text)
    seconds = 0.0
    for part in parts:
        seconds = seconds * 60 + int(part)
    return seconds
