"""Benchmark: the quasi-static path of library actuators (fast solver), against the
paper's incremental Nelder-Mead reference. Prints numbers; asserts nothing.

- seconds per inflation path for every pair (630) and a random sample of triples and
  quadruples, one core;
- the reference's seconds per path (0.02 mL increments) on the paper's named
  combinations and whether it finds the same transitions.

Run: python tests/benchmarks/bench_path.py [--triples N] [--quadruples N] [--write-docs]
"""

import argparse
import itertools
import random
import time

from labrig.cli.performance_doc import add_write_docs_argument, markdown_table, script_doc

# the state change between two 0.02 mL increments that the reference calls a snap
JUMP_ML = 0.3


def _moved_ml(transition) -> float:
    return max(
        abs(a - b) for a, b in zip(transition.post.v_i_ml, transition.pre.v_i_ml, strict=True)
    )


def _time_paths(actuators, deflate=False):
    from labrig.model.actuator.path import quasi_static_path
    from labrig.model.actuator.transitions import transitions

    found = 0
    t0 = time.perf_counter()
    for actuator in actuators:
        found += len(transitions(quasi_static_path(actuator, deflate=deflate)))
    return (time.perf_counter() - t0) / len(actuators), found


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--triples", type=int, default=1000)
    parser.add_argument("--quadruples", type=int, default=1000)
    add_write_docs_argument(parser)
    args = parser.parse_args()
    doc = script_doc(["path", "path-reference"], args.write_docs)

    from labrig.model.actuator.equilibria import Actuator
    from labrig.model.actuator.path import quasi_static_path
    from labrig.model.actuator.transitions import transitions
    from labrig.model.baselines.nelder_mead import reference_path
    from labrig.model.segments.catalog import LIBRARY_NAMES, analytical_segment

    segments = {name: analytical_segment(name) for name in LIBRARY_NAMES}
    # load (or compile) the solver's compiled loops before timing anything
    _time_paths([Actuator([segments[c] for c in LIBRARY_NAMES[:3]])], deflate=True)
    rng = random.Random(0)
    rows = []
    for n, count in ((2, None), (3, args.triples), (4, args.quadruples)):
        combos = list(itertools.combinations(LIBRARY_NAMES, n))
        drawn = "all" if count is None or count >= len(combos) else "random"
        if count is not None and count < len(combos):
            combos = rng.sample(combos, count)
        actuators = [Actuator([segments[c] for c in combo]) for combo in combos]
        per_path, found = _time_paths(actuators)
        per_cycle, _ = _time_paths(actuators[:200], deflate=True)
        rows.append(
            (
                n,
                f"{len(actuators):,} ({drawn})",
                f"{per_path * 1e3:.2f}",
                f"{per_cycle * 1e3:.2f}",
                f"{found / len(actuators):.1f}",
            )
        )
    header = (
        "segments",
        "actuators",
        "inflation (ms per path)",
        "inflation + deflation (ms, first 200)",
        "transitions per path",
    )
    doc.publish("path", markdown_table(header, rows, right={0, 1, 2, 3, 4}))

    named = [
        ("B46-T20", "B46-T22"),
        ("B48-T30", "B50-T20"),
        ("B44-T30", "B48-T26"),
        ("B40-T28", "B44-T30", "B50-T24"),
    ]
    # the reference's compiled minimiser loaded (or compiled) before timing it
    warm = Actuator([segments[n] for n in named[0]])
    reference_path(warm, 2.0, dv_ml=0.5, deflate=True, jump_ml=0.3)
    rows = []
    for names in named:
        actuator = Actuator([segments[n] for n in names])
        t0 = time.perf_counter()
        fast_path = quasi_static_path(actuator, deflate=True)
        t_fast = time.perf_counter() - t0
        fast = transitions(fast_path)
        t0 = time.perf_counter()
        ref = reference_path(
            actuator, fast_path.v_end_ml, dv_ml=0.02, deflate=True, jump_ml=JUMP_ML
        )
        t_ref = time.perf_counter() - t0
        # a snap that moves less than the reference's jump threshold is, to the
        # reference, part of the quasi-static motion: left out of the comparison, counted
        small = [t for t in fast if not t.stable and _moved_ml(t) < JUMP_ML]
        compared = [t for t in fast if t not in small]
        same = [(t.alpha, t.beta, t.stable, t.direction) for t in compared] == [
            (t.alpha, t.beta, t.stable, t.direction) for t in ref.transitions
        ]
        worst = max(
            (
                abs(f.v_ml - (r.v_ml + 0.01 * r.direction))
                for f, r in zip(compared, ref.transitions, strict=False)
            ),
            default=0.0,
        )
        rows.append(
            (
                " + ".join(names),
                f"{t_fast * 1e3:.1f}",
                f"{t_ref:.2f}",
                f"{len(ref.v_ml):,}",
                "yes" if same else "no",
                f"{worst:.3f}",
                ", ".join(f"{t.v_ml:.2f} mL ({_moved_ml(t):.2f})" for t in small) or "-",
            )
        )
    header = (
        "actuator",
        "fast path (ms)",
        "Nelder-Mead, 0.02 mL (s)",
        "increments",
        "same transitions",
        "max abs dv (mL)",
        f"fast-path snaps under the {JUMP_ML} mL jump (mL moved)",
    )
    doc.publish("path-reference", markdown_table(header, rows, right={1, 2, 3, 5}))


if __name__ == "__main__":
    main()
