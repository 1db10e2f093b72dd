"""Benchmark: snap-through detection against the simulated plant's own snaps, and the
time to analyse a run. Prints numbers; asserts nothing.

Each case is a library actuator run on the plant (``tests/support/simulated_runs.py``: pump at
20 mL/min, 1 kHz pressure with MPX5100-like noise, a 30 fps camera with 0.01 mm of
tracking noise) for three repetitions; a true snap is a peak of the plant's internal
flow, and the error is the detected volume minus the supplied volume at that peak. The
length change: every true snap whose noise-free jump (``_true_jump``: lines through
the plant's own length on either side of its internal flow) is at least 0.3 mm must
have a measured dl, and its error against that jump is summed up as the rms. R is the
plant's flow resistance (1 kPa s/mL: water through the fittings; 0.05: the slow limit
where the plant follows the model).

Run: python tests/benchmarks/bench_analysis.py [--write-docs]
"""

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from support.simulated_runs import simulate_run

from labrig.analysis import analyse
from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc

CASES = [  # segments, volume (mL), R (kPa s/mL)
    (("B46-T20", "B46-T22"), 22.0, 1.0),
    (("B48-T28", "B50-T20"), 32.0, 1.0),
    (("B44-T22", "B50-T20"), 36.0, 1.0),
    (("B46-T30", "B48-T20"), 24.0, 1.0),
    (("B40-T22", "B48-T20"), 28.0, 1.0),
    (("B44-T26", "B48-T20"), 28.0, 1.0),
    (("B44-T22", "B50-T20"), 36.0, 0.05),
    (("B40-T22", "B48-T20"), 28.0, 0.05),
    (("B48-T30", "B50-T20"), 38.0, 0.1),  # the demo's actuator at the rig's default R
    (("B44-T22", "B50-T20"), 36.0, 0.1),
    (("B40-T22", "B48-T20"), 28.0, 0.1),
    (("B46-T30", "B48-T20"), 24.0, 0.1),
    (("B46-T20",), 20.8, 1.0),  # a single segment: never snaps
]


def main() -> None:
    parser = argparse.ArgumentParser()
    add_write_docs_argument(parser)
    doc = script_doc(["analysis"], parser.parse_args().write_docs)
    rows = []
    errors_all, dl_errors_all, dl_due_all, dl_seen_all = [], {}, 0, 0
    snaps_all = invented_all = on_curve_all = 0
    with tempfile.TemporaryDirectory() as folder:
        for k, (segments, volume_ml, resistance) in enumerate(CASES):
            for noise_kpa in (0.05, 0.3):
                run = simulate_run(
                    Path(folder) / f"case{k}_{noise_kpa}.h5",
                    segments,
                    volume_ml=volume_ml,
                    repetitions=3,
                    resistance_kpa_s_per_ml=resistance,
                    noise_kpa=noise_kpa,
                    seed=k + 1,
                    fps=30.0,
                )
                t0 = time.perf_counter()
                result = analyse(run.path, segments=list(segments))  # with the model's path
                elapsed = time.perf_counter() - t0
                found = [t for rep in result.repetitions for t in rep.transitions]
                errors, used, dl_errors, dl_due, dl_seen = [], set(), [], 0, 0
                for snap in run.snaps:
                    near = [
                        (abs(t.v_ml - snap.v_ml), i)
                        for i, t in enumerate(found)
                        if t.repetition == snap.repetition and t.direction == snap.direction
                        and abs(t.v_ml - snap.v_ml) < 1.5 and i not in used
                    ]  # fmt: skip
                    big = abs(snap.dl_mm) >= 0.3
                    dl_due += big
                    if near:
                        _, i = min(near)
                        used.add(i)
                        errors.append(found[i].v_ml - snap.v_ml)
                        if big and np.isfinite(found[i].dl_mm):
                            dl_seen += 1
                            dl_errors.append(found[i].dl_mm - snap.dl_mm)
                errors_all += errors
                snaps_all += len(run.snaps)
                invented = [t for i, t in enumerate(found) if i not in used]
                invented_all += len(invented)
                # a steep stable stretch is a bump of dp/dv like a snap's; compare tells
                on_curve = sum(result.on_the_models_curve(t) for t in invented)
                on_curve_all += on_curve
                dl_errors_all.setdefault(resistance, []).extend(dl_errors)
                dl_due_all += dl_due
                dl_seen_all += dl_seen
                dl_rms = f"{np.sqrt(np.mean(np.square(dl_errors))):.3f}" if dl_errors else "-"
                worst = f"{np.max(np.abs(errors)):.3f}" if errors else "-"
                rms = f"{np.sqrt(np.mean(np.square(errors))):.3f}" if errors else "-"
                rows.append(
                    (
                        " + ".join(segments),
                        f"{resistance:g}",
                        f"{noise_kpa:g}",
                        f"{len(errors)} of {len(run.snaps)}",
                        f"{len(invented)} ({on_curve})",
                        worst,
                        rms,
                        f"{dl_seen} of {dl_due}",
                        dl_rms,
                        f"{elapsed:.2f}",
                    )
                )
    header = (
        "actuator",
        "R (kPa s/mL)",
        "noise (kPa)",
        "snaps found",
        "invented (on the model's curve)",
        "max abs error (mL)",
        "rms (mL)",
        "dl measured (abs dl >= 0.3 mm)",
        "dl error rms (mm)",
        "analyse (s)",
    )
    summary = [
        f"All: {len(errors_all)} of {snaps_all} snaps found, {invented_all} invented "
        f"({on_curve_all} of them on the model's curve); volume "
        f"error max {np.max(np.abs(errors_all)):.3f} mL, "
        f"rms {np.sqrt(np.mean(np.square(errors_all))):.3f} mL; "
        f"dl measured at {dl_seen_all} of {dl_due_all} snaps with abs dl >= 0.3 mm."
    ]
    for resistance, dl_errors in sorted(dl_errors_all.items()):
        e = np.array(dl_errors)
        summary.append(
            f"dl error at R = {resistance:g} kPa s/mL: rms {np.sqrt(np.mean(e**2)):.3f} mm, "
            f"max {np.max(np.abs(e)):.3f} mm over {len(e)} snaps."
        )
    table = markdown_table(header, rows, right=set(range(1, 10)))
    doc.publish("analysis", "\n\n".join([table, *summary]))


if __name__ == "__main__":
    main()
