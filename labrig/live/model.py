"""The model's prediction for the live page: the specimen's quasi-static path over the
protocol's volumes, computed once in the background.

The same prediction the analysis compares a finished run with
(``labrig.analysis.compare.predict``): inflated to the protocol's largest volume and, if
the protocol withdraws, deflated back. It can take seconds (the path solver's first
compile), so the page asks again until it is ready; a specimen the model cannot predict
(a segment that is not in the library) gives the reason instead of a curve.
"""

from __future__ import annotations

import threading

import numpy as np

from labrig.config.protocol import Protocol, plan


def _values(a: np.ndarray, digits: int) -> list:
    return [round(float(x), digits) if np.isfinite(x) else None for x in a]


def prediction_json(protocol: Protocol) -> dict:
    """The prediction as the page draws it (``ready`` true; ``error`` if none)."""
    from labrig.analysis.compare import predict
    from labrig.errors import LabrigError
    from labrig.model.segments.catalog import load_segment

    the_plan = plan(protocol)
    segments = list(protocol.specimen.segments)
    if not protocol.specimen.has_model:
        return {
            "ready": True,
            "segments": segments,
            "error": "the specimen has no model (specimen.model: none): its segments are labels",
        }
    try:
        curves = [load_segment(name) for name in segments]
        prediction = predict(
            curves,
            protocol.specimen.fittings_length_mm,
            the_plan.max_volume_ml,
            deflate=the_plan.withdrawn_ml > 0,
        )
    except LabrigError as exc:
        return {"ready": True, "segments": segments, "error": str(exc)}
    return {
        "ready": True,
        "segments": segments,
        "v_ml": _values(prediction.v_ml, 4),
        "p_kpa": _values(prediction.p_kpa, 3),
        "l_mm": _values(prediction.l_mm, 3),
        "direction": [int(d) for d in prediction.direction],
        "transitions": [
            {
                "direction": "inflate" if t.direction > 0 else "deflate",
                "v_ml": t.v_ml,
                "type": t.type,
                "stable": t.stable,
                "dp_kpa": t.dp_kpa,
                "dl_mm": t.dl_mm,
            }
            for t in prediction.transitions
        ],
    }


class BackgroundPrediction:
    """``prediction_json`` computed in a daemon thread; ``json`` is
    ``{"ready": false}`` until it is done."""

    def __init__(self, protocol: Protocol) -> None:
        self.json: dict = {"ready": False}
        self._protocol = protocol
        self._thread = threading.Thread(target=self._compute, name="live-model", daemon=True)

    def start(self) -> BackgroundPrediction:
        self._thread.start()
        return self

    def _compute(self) -> None:
        try:
            self.json = prediction_json(self._protocol)
        except Exception as exc:  # a model failure must not end the run it accompanies
            self.json = {"ready": True, "error": f"the model failed: {exc!r}"}
