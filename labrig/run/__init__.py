"""Running a protocol on a rig: the runner, the interlocks that stop the pump on a fault,
and the dry run that says what a protocol will do before it does.
"""

from labrig.exports import lazy_exports

__getattr__, __dir__ = lazy_exports(
    "labrig.run",
    {
        "runner": ["Runner"],
        "interlocks": ["InterlockMonitor"],
        "dry_run": ["dry_run_report"],
    },
)
