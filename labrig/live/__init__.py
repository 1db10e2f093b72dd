"""The live view of a run in a browser: ``labrig run --live`` and ``labrig watch``.

``state`` digests what the run appends (never blocking it), ``series`` gives each point
its volume, ``model`` computes the prediction the page draws dashed, ``server`` serves
the page and its JSON on 127.0.0.1, ``follow`` reads a run file another process is
recording (SWMR), and ``session`` ties them together. The page itself is ``static/``.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.live",
    {
        "session": ["LiveView"],
        "follow": ["FileFollower"],
    },
)
