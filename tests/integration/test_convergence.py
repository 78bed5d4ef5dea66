"""Convergence order of the engine's home-grown Dormand-Prince 5(4) steppers.

Three implementations of the same method exist: ``hybridsim._rk`` (the
Python path's RK45, scipy's arithmetic), the vectorized batch integrator and
the compiled kernel. Each is run with a fixed step h (``first_step`` =
``max_step`` = h and tolerances so loose that no step is rejected or
shortened) on the harmonic oscillator x'' = -x over [0, 4], whose solution
is known. The global error at t = 4 must fall like h^5 (the propagated
5th-order solution, local extrapolation): the least-squares slope of
log(error) against log(h) over h = 1/2, 1/4, 1/8, 1/16 lies within 0.3 of 5.
Why 0.3: at these step sizes the next term of the error expansion is
O(h) relative to the leading one, which
moves a four-point slope by about 0.15; round-off (1e-16 against errors
above 1e-10 here) does not enter. The three implementations must also give
the same errors to 1e-14 absolute: they are one method, the same operations
possibly in another order (round-off of 1e-16 per step over 64 steps).
"""
import numpy as np
import pytest
from paths import Linear, run

T_END = 4.0
STEPS = (0.5, 0.25, 0.125, 0.0625)     # exact in binary: no sliver of a last step


def oscillator():
    """x' = (x2, -x1) and a jump set never reached."""
    return Linear(np.array([[0.0, 1.0], [-1.0, 0.0]]), np.eye(2), np.zeros(2),
                  np.array([1.0, 0.0]), 100.0)


def errors(path):
    case = oscillator()
    x0 = np.array([1.0, 0.0])
    exact = np.array([np.cos(T_END), -np.sin(T_END)])
    out = []
    for h in STEPS:
        arc = run(path, case, x0, t_max=T_END, first_step=h, max_step=h, rtol=1e3,
                  atol=1e3, warn=False)
        assert arc.termination.name == "T_MAX"
        steps = np.diff(arc.t)
        np.testing.assert_allclose(steps, h, rtol=1e-9)     # fixed steps indeed
        out.append(float(np.linalg.norm(arc.xf - exact)))
    return np.array(out)


def test_dormand_prince_converges_with_order_five(path):
    err = errors(path)
    slope = np.polyfit(np.log(STEPS), np.log(err), 1)[0]
    assert abs(slope - 5.0) < 0.3, (slope, err)
    assert np.all(np.diff(err) < 0)


@pytest.mark.paths(only=("vectorized", "compiled"))
def test_every_stepper_is_the_same_method(path):
    np.testing.assert_allclose(errors(path), errors("python"), rtol=0, atol=1e-14)
