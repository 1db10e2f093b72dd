"""The compiled functions' dispatchers (``labrig.model.actuator.dispatcher``): compiled code
calls a function through its internal twin, whose library is only linked into its
callers' (no machine code of its own), and gets the same numbers as Python's call."""

import pytest

from labrig.model.actuator import jit

pytestmark = pytest.mark.skipif(not jit.COMPILED, reason="the dispatchers of a compiling process")


def test_compiled_code_links_the_internal_twin_of_a_function_python_calls():
    from labrig.model.actuator.dispatcher import LinkOnlyLibrary

    @jit.njit(_nrt=False)
    def inner(x):
        return x * 0.1 + 0.2

    @jit.njit(**jit.INTERNAL)
    def middle(x):
        return inner(x) - inner(x + 1.0)

    @jit.njit()
    def outer(x):
        return middle(x) * 3.0

    assert outer(3.0) == ((3.0 * 0.1 + 0.2) - (4.0 * 0.1 + 0.2)) * 3.0
    assert not inner.signatures  # Python never called it: nothing compiled for Python
    for internal in (inner.twin, middle):
        [signature] = internal.signatures
        assert isinstance(internal.overloads[signature].library, LinkOnlyLibrary)
    assert middle.twin is None  # internal already
    assert inner(3.0) == 3.0 * 0.1 + 0.2  # and Python's call compiles its own
    assert len(inner.signatures) == 1


def test_calls_with_constants_compile_one_signature():
    @jit.njit(**jit.INTERNAL)
    def scaled(x, k):
        return x * k

    @jit.njit()
    def both(x):
        return scaled(x, 2) + scaled(x, 3)

    assert both(1.5) == 7.5
    assert len(scaled.signatures) == 1  # int64, not Literal[int](2) and Literal[int](3)
