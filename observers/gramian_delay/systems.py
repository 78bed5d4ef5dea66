r"""The hybrid systems of Mazenc & Malisoff (2022) on :mod:`hybridsim`.

* :class:`Plant` -- system (1), output Y (or (Y, xi_2) for the oracle).
* :class:`DCMotor` -- the DC motor (65) of Section V as a :class:`Plant`,
  with its coordinates (66)-(67), design and observers.
* :class:`PiecewiseDisturbed` -- a plant (1) whose delta1, delta2 are
  piecewise constant with their values in its state: each row of a batch
  its own disturbances (Theorem 1's searches).
* :func:`smooth_noise` -- a seeded smooth measurement disturbance delta_2.
* :class:`GramianObserver` -- the dynamic extension (7) (Theorem 1), input Y;
  :meth:`GramianObserver.estimate` evaluates (13) along a finished run.
* :class:`SampledGramianObserver` -- the observer (39) (Theorem 2): omega
  reset to Y(t_j) at each sample; (13) enters omega's flow through the run's
  history (a delay equation).
* :func:`estimate_along` -- xi_e of (13) along a run.

Two realisations of psi_2 of (7) (``realisation=``):

``"literal"`` (default)
    psi_2 is a state flowing by psi_2' = -(A1^T + 2kI) psi_2 + H(Y - xi2_hat),
    as printed. Unstable when 2k < -min Re eig(A1) (DC motor, k = 75: growth
    +47.2/s); (13) then subtracts two terms growing like e^{47 t}.
``"reset"``
    (13) needs psi_2 only through the window integral
    I_2(t) = psi_2(t) - e^{-(A1^T+2kI) tau} psi_2(t - tau)
    = int_{t-tau}^t e^{-(A1^T+2kI)(t-s)} H (Y(s) - xi2_hat(s)) ds (identity (53)).
    A timer rho resets every tau (at t0 + tau, t0 + 2 tau, ...): p flows as
    psi_2 and is reset to 0; phi = e^{-(A1^T+2kI) rho} P carries the window
    integral P = p(t_r^-) of the last reset; then, for t in [t_r, t_r + tau),

        I_2(t) = p(t) + phi(t) - e^{-(A1^T+2kI) tau} p(t - tau),

    with p(t - tau) read in the previous reset interval (from the run's
    history during a run, from the arc afterwards). Every state is bounded
    by e^{|growth| tau} times the window's input (about 112 on the DC
    motor at k = 75), whatever the horizon: no growing mode survives a
    reset. In exact arithmetic I_2 is the same, so (13) and Theorem 1's
    exactness are unchanged.

On the compiled path (``backend="compiled"``, :func:`hybridsim.compiled.lower`)
the plant (1) runs its own maps, rewritten from source with the callables
they call (Psi, delta1, delta2 written on the last axis, ``batch = True``:
those of :func:`~observers.gramian_delay.dc_motor` and :func:`smooth_noise`),
and (39) in the literal realisation runs its compiled form (reasons beside
:meth:`SampledGramianObserver.compiled_component`): its compiled flow reads
psi(t - tau) from the past state the engine hands it
(``Component(delays=(tau,))``).

Examples
--------
>>> import numpy as np
>>> from observers import gramian_delay as gd
>>> ex = gd.dc_motor(75.0, 0.1, disturbed=False)
>>> obs = ex.continuous_observer(realisation="reset")
>>> obs.state_dim          # xi1_hat (2), xi2_hat (1), psi1 (2), p, phi, P (2 each), rho
12
"""
from __future__ import annotations

import cmath
import functools
import math
import numbers

import numpy as np

import hybridsim as hs

from .._common import matrix, scalar, vector
from .design import GramianDesign, ObserverForm, gramian_design, observer_form

__all__ = ["Plant", "DCMotor", "PiecewiseDisturbed", "GramianObserver", "SampledGramianObserver",
           "estimate_along", "REALISATIONS", "smooth_noise"]

#: The realisations of psi_2 of (7) (module docstring).
REALISATIONS = ("literal", "reset")


def _signal(name, fn, dim):
    """A callable t -> (dim,) array (None: zero); a signal made here is not wrapped again.

    On the last axis: times ``t`` of shape (N,) give (N, dim), in one call
    where ``fn`` declares it takes arrays (``fn.batch = True``: the signals
    of :func:`dc_motor` and :func:`smooth_noise`), else one call per time.
    """
    if getattr(fn, "_signal_dim", None) == dim:
        return fn
    if fn is None:
        def signal(t):
            return np.zeros(np.shape(t) + (dim,))
        signal._zero = True
    elif not callable(fn):
        raise TypeError(f"{name} must be callable t -> ({dim},) array or None, "
                        f"got {type(fn).__name__}")
    elif getattr(fn, "batch", False):
        def signal(t):
            t = np.asarray(t, dtype=float)
            return np.asarray(fn(t), dtype=float).reshape(t.shape + (dim,))
    else:
        def signal(t):      # fn takes one time: a batch of times is read one by one
            if np.ndim(t) == 0:
                return np.asarray(fn(t), dtype=float).reshape(dim)
            t = np.asarray(t, dtype=float)
            return np.array([np.asarray(fn(float(s)), dtype=float).reshape(dim)
                             for s in t.ravel()]).reshape(t.shape + (dim,))
    signal._signal_dim = dim
    signal._one_time = fn is not None and not getattr(fn, "batch", False)
    return signal


@functools.cache
def _no_psi(n):
    def psi(p, y, t):             # Psi = 0 (never called: the branch is constant)
        return np.zeros(n)
    return psi


def _psi_refusal(Psi):
    """Why a Psi's own code does not run compiled (a sentence naming it), or None."""
    why = getattr(Psi, "refusal", None)
    if why is None and not getattr(Psi, "batch", False):
        why = ("its Psi is a Python callable without a batch form (Psi.batch = True, on the "
               "last axis; see gramian_delay.Plant)")
    return why


def smooth_noise(sigma, dim=1, *, seed=None, n_modes=8, f_max=50.0):
    r"""A seeded smooth random signal t -> (dim,) of RMS about ``sigma``.

    ``sum_i a_i sin(2 pi f_i t + phi_i)`` with ``n_modes`` frequencies drawn
    uniformly in (0, f_max] Hz, Gaussian amplitudes scaled so that the RMS
    over a long horizon is ``sigma``, uniform phases. Smooth, so the
    integrator is not forced to resolve a discontinuous input. A measurement
    disturbance delta_2 of (1) for :func:`~observers.gramian_delay.simulate`'s
    ``noise=``.

    Parameters
    ----------
    sigma : float
        RMS (>= 0).
    dim : int
    seed : int or numpy Generator, optional
    n_modes : int
    f_max : float

    Returns
    -------
    callable
        ``t -> (dim,)`` array, on the last axis (``batch = True``): it runs
        compiled as written (:class:`Plant`'s notes).

    Examples
    --------
    >>> n = smooth_noise(1e-3, seed=0)
    >>> n(0.5).shape
    (1,)
    """
    sigma = scalar("sigma", sigma, nonneg=True)
    f_max = scalar("f_max", f_max, positive=True)
    if isinstance(dim, bool) or not isinstance(dim, numbers.Integral) or dim < 1:
        raise ValueError(f"dim must be a positive int, got {dim!r}")
    if isinstance(n_modes, bool) or not isinstance(n_modes, numbers.Integral) or n_modes < 1:
        raise ValueError(f"n_modes must be a positive int, got {n_modes!r}")
    rng = np.random.default_rng(seed)
    f = rng.uniform(0.0, f_max, size=(n_modes, dim)) + f_max / (10 * n_modes)
    a = rng.normal(size=(n_modes, dim))
    a *= sigma * np.sqrt(2.0) / np.maximum(np.linalg.norm(a, axis=0), 1e-300)
    ph = rng.uniform(0.0, 2 * np.pi, size=(n_modes, dim))

    def noise(t):                   # on the last axis: times (N,) -> (N, dim)
        t = np.asarray(t, dtype=float)[..., None, None]
        return np.sum(a * np.sin(2 * np.pi * f * t + ph), axis=-2)
    noise.batch = True
    return noise


class Plant(hs.HybridSystem):
    r"""System (1): chi' = M chi + Psi(N chi, t) + delta1(t), Y = N chi + delta2(t).

    A hybrid system with empty jump set and no input (u(t) enters through
    Psi's time argument). Its output is Y (q,), or ``(Y, N chi)`` (2q,)
    when ``oracle=True`` (to feed the literal reading of (39), which needs
    the unmeasured xi_2 = N chi).

    Parameters
    ----------
    M : (n, n) array_like
    N : (q, n) array_like
    Psi : callable, optional
        ``Psi(y, t) -> (n,)``.
    delta1 : callable, optional
        ``t -> (n,)`` disturbance on the dynamics.
    delta2 : callable, optional
        ``t -> (q,)`` measurement disturbance.
    oracle : bool

    Notes
    -----
    A ``Psi`` that declares ``Psi.batch = True`` is written on the last axis
    (``Psi(Y, t) -> (N, n)`` for ``Y`` (N, q) and ``t`` (N,), as well as one
    ``(q,)``, t): with it (or without Psi) the plant is ``vectorized``, and
    :func:`hybridsim.simulate_many` integrates a batch of plants at once
    (the disturbances are read per time, in one call where they declare
    ``batch = True``).

    The compiled path (``backend="compiled"``) runs these maps as written:
    their source, with the code of ``Psi``, ``delta1`` and ``delta2``, is
    rewritten for numba (:func:`hybridsim.compiled.lower`; M, N and the
    numbers the callables read become parameters). A callable of one time
    only (no ``batch = True``) is refused by name (:meth:`compiled_refusal`),
    and one whose code numba cannot compile by numba's message naming its
    line.

    References
    ----------
    Mazenc & Malisoff (2022), eq. (1).
    """

    def __init__(self, M, N, Psi=None, *, delta1=None, delta2=None, oracle=False):
        self.M = matrix("M", M)
        n = self.M.shape[0]
        if self.M.shape != (n, n):
            raise ValueError(f"M must be square, got shape {self.M.shape}")
        self.N = matrix("N", N, (None, n))
        q = self.N.shape[0]
        if Psi is not None and not callable(Psi):
            raise TypeError(f"Psi must be callable, got {type(Psi).__name__}")
        self.Psi = Psi
        if Psi is not None:
            _probe_shape("Psi", lambda: Psi(np.zeros(q), 0.0), (n,), f"(n = {n} states)")
        self.delta1 = _signal("delta1", delta1, n)
        self.delta2 = _signal("delta2", delta2, q)
        # a zero disturbance is not called during a run
        self._d1 = None if getattr(self.delta1, "_zero", False) else self.delta1
        self._d2 = None if getattr(self.delta2, "_zero", False) else self.delta2
        self.oracle = bool(oracle)
        self.state_dim = n
        self.output_dim = 2 * q if oracle else q
        # maps over (N, n) batches where Psi takes the last axis (or there is none)
        self.vectorized = Psi is None or bool(getattr(Psi, "batch", False))

    def flow_map(self, x, t):
        """chi' of (1), on the last axis (x (n,) or a batch (N, n) with t (N,))."""
        x = np.asarray(x, dtype=float)
        dx = x @ self.M.T
        if self._d1 is not None:
            dx += self._d1(t)
        if self.Psi is not None:
            dx += np.asarray(self.Psi(x @ self.N.T, t), dtype=float)
        return dx

    def compiled_refusal(self):
        """Why the plant's maps do not run compiled (a sentence naming the callable), or None."""
        why = None if self.Psi is None else _psi_refusal(self.Psi)
        for name, sig in (("delta1", self._d1), ("delta2", self._d2)):
            if why is None and sig is not None and sig._one_time:
                why = (f"its {name} is a Python callable of t without a batch form "
                       f"(batch = True, on the last axis; see gramian_delay.Plant)")
        return why

    def output(self, x, t, j):
        """Y = N chi + delta2(t) (then N chi with ``oracle``), on the last axis."""
        y = np.asarray(x, dtype=float) @ self.N.T
        Y = y if self._d2 is None else y + self._d2(t)
        return np.concatenate((Y, y), axis=-1) if self.oracle else Y


class DCMotor(Plant):
    r"""The single-link manipulator with DC motor (64)-(65) as a plant (1), with (66)-(67).

    chi = (angle, angular velocity, armature current), output the angle:

    .. math::
        \dot\chi = M\chi + \Psi(\chi_1, t) + \delta_1(t),\quad
        M = \begin{bmatrix}0 & 1 & 0\\ 0 & -a_2 & b_1\\ 0 & -a_3 & -a_4\end{bmatrix},\quad
        \Psi = (0, -a_1\sin\chi_1, b_0 u(t)),\quad Y = \chi_1 + \delta_2(t).

    Besides the plant it carries what a run of the paper's observers needs:
    the coordinates (66) (``form``: xi1 = (chi2, chi3), xi2 = chi1, with A1,
    A2, F1, F2 of (67)), the design (5)-(6) for ``k`` and ``tau``, the
    Lipschitz constants ``K1 = a1``, ``K2 = k`` of F1, F2 (Section V) and an
    initial state ``chi0``; :meth:`continuous_observer` and
    :meth:`sampled_observer` build the observers (7) and (39) for it. The
    paper's values and our choices are given by
    :func:`~observers.gramian_delay.dc_motor`.

    Parameters
    ----------
    params : dict
        b0, b1, a1, a2, a3, a4 of (65).
    k, tau : float
        The constant of (2) and the delay.
    u : callable
        The control ``t -> float``; on the last axis with ``u.batch = True``
        (:func:`~observers.gramian_delay.dc_motor`'s), the plant and the
        observer (39) run compiled (:class:`Plant`'s notes).
    delta1, delta2 : callable, optional
        ``t -> (3,)``, ``t -> (1,)``; None means zero.
    chi0 : (3,) array_like
        The initial state of the runs.
    oracle : bool
        Output (Y, chi1) instead of Y (for (39) with estimate="xi2").

    Examples
    --------
    >>> import numpy as np
    >>> from observers.gramian_delay import DCMotor
    >>> p = dict(b0=40.0, b1=15.0, a1=35.0, a2=1.0, a3=36.4, a4=200.0)
    >>> motor = DCMotor(p, 100.0, 0.1, u=np.sin, chi0=[0.5, -1.0, 0.2])
    >>> motor.form.A1.tolist(), motor.K1                          # (67)
    ([[-1.0, 15.0], [-36.4, -200.0]], 35.0)

    References
    ----------
    Mazenc & Malisoff (2022), Section V, eqs. (64)-(67).
    """

    def __init__(self, params, k, tau, *, u, delta1=None, delta2=None, chi0=(0.0, 0.0, 0.0),
                 oracle=False):
        missing = {"b0", "b1", "a1", "a2", "a3", "a4"} - set(params)
        if missing:
            raise ValueError(f"params lacks {sorted(missing)}")
        p = {key: scalar(key, params[key]) for key in ("b0", "b1", "a1", "a2", "a3", "a4")}
        if not callable(u):
            raise TypeError(f"u must be callable t -> float, got {type(u).__name__}")
        M = np.array([[0.0, 1.0, 0.0], [0.0, -p["a2"], p["b1"]], [0.0, -p["a3"], -p["a4"]]])
        Nmat = np.array([[1.0, 0.0, 0.0]])
        a1, b0 = p["a1"], p["b0"]

        u_t = _signal("u", u, 1)

        def Psi(y, t):                      # on the last axis: y (N, 1) with t (N,) too
            y = np.asarray(y, dtype=float)
            out = np.zeros(y.shape[:-1] + (3,))
            out[..., 1] = -a1 * np.sin(y[..., 0])
            out[..., 2] = b0 * u_t(t)[..., 0]
            return out
        Psi.batch = True

        if not getattr(u, "batch", False):
            Psi.refusal = ("its control u is a Python callable of t without a batch form "
                           "(u.batch = True, on the last axis; see gramian_delay.Plant)")
        super().__init__(M, Nmat, Psi, delta1=delta1, delta2=delta2, oracle=oracle)
        self.params = p
        self.u = u
        self.form = observer_form(M, Nmat, Psi, P=[[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], k=k)
        self.design = gramian_design(self.form.A1, self.form.A2, self.form.k, tau)
        self.K1, self.K2 = p["a1"], float(self.form.k)
        self.chi0 = vector("chi0", chi0, 3)

    def xi(self, chi):
        """(66)'s coordinates of plant states (time-major (N, 3) or (3,))."""
        return self.form.to_xi(chi)

    def continuous_observer(self, t0=0.0, *, realisation="literal"):
        """The observer (7) of Theorem 1 for this motor.

        It carries this plant and its ``form``, so that
        :func:`~observers.gramian_delay.simulate` and
        :func:`~observers.gramian_delay.errors` need nothing else.
        """
        obs = GramianObserver(self.design, self.form.F1, self.form.F2, t0=t0,
                              realisation=realisation)
        obs.plant, obs.form = self, self.form
        return obs

    def sampled_observer(self, **kw):
        """The observer (39) of Theorem 2 (keywords of SampledGramianObserver)."""
        obs = SampledGramianObserver(self.design, self.form.F1, self.form.F2, **kw)
        obs.plant, obs.form = self, self.form
        return obs


class PiecewiseDisturbed(Plant):
    r"""A plant (1) with piecewise-constant disturbances whose values are in its state.

    State ``(chi, d1, d2)``: chi (n,) of (1), then the values of delta1
    ((pieces, n), row-major) and delta2 ((pieces, q)) on the ``pieces``
    intervals of width ``t_end / pieces`` (the last held after ``t_end``:
    :class:`hybridsim.falsification.PiecewiseConstant`'s rule), which do
    not flow. Each row of a batch (:func:`hybridsim.simulate_many`) thus
    carries its own disturbances through one model. The flow and the output
    are ``plant``'s (its own delta1, delta2 replaced by these).

    Parameters
    ----------
    plant : Plant
        M, N, Psi and ``oracle`` are taken from it.
    t_end : float
    pieces : int

    Examples
    --------
    >>> import numpy as np
    >>> from observers import gramian_delay as gd
    >>> p = gd.PiecewiseDisturbed(gd.dc_motor(100.0, 0.1), 0.3, 6)
    >>> x0 = p.initial_state([0.5, -1, 0.2], np.ones((6, 3)), np.full((6, 1), 1e-3))
    >>> p.state_dim, float(p.output(x0, 0.0, 0)[0])
    (27, 0.501)
    """

    def __init__(self, plant, t_end, pieces):
        if not isinstance(plant, Plant):
            raise TypeError(f"plant must be a gramian_delay.Plant, got {type(plant).__name__}")
        super().__init__(plant.M, plant.N, plant.Psi, oracle=plant.oracle)
        self.t_end = scalar("t_end", t_end, positive=True)
        if isinstance(pieces, bool) or not isinstance(pieces, numbers.Integral) or pieces < 1:
            raise ValueError(f"pieces must be a positive int, got {pieces!r}")
        self.pieces = int(pieces)
        n, q = self.M.shape[0], self.N.shape[0]
        self.n_chi = n
        self.state_dim = n + self.pieces * (n + q)

    def initial_state(self, chi0, delta1, delta2):
        """(chi0, delta1's values (pieces, n), delta2's (pieces, q)) as one state."""
        n, q, k = self.n_chi, self.N.shape[0], self.pieces
        return np.concatenate([vector("chi0", chi0, n), matrix("delta1", delta1, (k, n)).ravel(),
                               matrix("delta2", delta2, (k, q)).ravel()])

    def _values(self, x, t):
        """delta1 (..., n) and delta2 (..., q) of each state at its time.

        The piece's values as a sum over the pieces of each one's values times
        1 where it is the piece of t and 0 elsewhere (exactly the piece's
        values: every other term is zero), on the last axis of x and t.
        """
        n, q, k = self.n_chi, self.N.shape[0], self.pieces
        i = np.minimum(np.maximum(np.floor_divide(t, self.t_end / k), 0.0), k - 1.0)
        d1 = x[..., n:2 * n].T * (i == 0)
        d2 = x[..., n + k * n:n + k * n + q].T * (i == 0)
        for m in range(1, k):
            a, b = n + m * n, n + k * n + m * q
            d1 = d1 + x[..., a:a + n].T * (i == m)
            d2 = d2 + x[..., b:b + q].T * (i == m)
        return d1.T, d2.T

    def flow_map(self, x, t):
        """chi' of (1) with this state's delta1, the values' 0, on the last axis."""
        x = np.asarray(x, dtype=float)
        out = np.zeros(x.shape)
        out[..., :self.n_chi] = super().flow_map(x[..., :self.n_chi], t) + self._values(x, t)[0]
        return out

    def output(self, x, t, j):
        """Y = N chi + delta2 (then N chi with ``oracle``), on the last axis."""
        x = np.asarray(x, dtype=float)
        y = x[..., :self.n_chi] @ self.N.T
        Y = y + self._values(x, t)[1]
        return np.concatenate((Y, y), axis=-1) if self.oracle else Y


@functools.cache
def _sampled_maps(m, q, n, psi, sampling, xi2):
    r"""Compiled maps of (39) (literal realisation) with (7) and (13).

    State ``(xi1_hat, xi2_hat, psi1, psi2, omega, sigma, kappa)``; parameters
    in the order of :meth:`SampledGramianObserver.compiled_component`, then
    (the flow only) the state at t - tau. ``psi`` is the form's Psi compiled
    from its own source, ``psi(p', y, t)`` with its numbers ``p'`` in ``p``
    (None: Psi = 0); ``sampling`` "period", "instants" or "gaps";
    ``xi2``: (13) reads xi_2 from the input's second half, else omega.
    """
    from hybridsim.compiled import compiled_matvec
    mv = compiled_matvec()
    e = 3 * m + q
    r = e + q + 2
    mm, mq = m * m, m * q
    # parameter offsets
    oA1 = 0
    oA2 = oA1 + mm
    ok = oA2 + q * m
    oH = ok + 1
    omA = oH + mq
    oR = omA + mm
    oSi = oR + mq
    oE1 = oSi + mm
    oE2 = oE1 + 1
    otau = oE2 + mm
    ot0 = otau + 1
    oVr = ot0 + 1
    oVi = oVr + mm
    owr = oVi + mm
    owi = owr + m
    oWr = owi + m
    oWi = oWr + mm
    oL1 = oWi + mm
    oL2 = oL1 + mq
    oP = oL2 + q * q
    oN = oP + m * n
    os_ = oN + q * n               # period | (T_low, T_bar) | (K, offset of the instants)
    opsi = os_ + 2                 # (offset, size) of Psi's parameters
    has_psi = psi is not None
    psi = psi if has_psi else _no_psi(n)

    def decay(h, p):
        """(e^{-k h}, e^{-(A1^T + 2kI) h}) for h < tau, from the modes (GramianDesign.decay)."""
        ee = np.empty(m, np.complex128)
        for i in range(m):
            ee[i] = cmath.exp(complex(p[owr + i] * h, p[owi + i] * h))
        E2 = np.empty((m, m))
        for a in range(m):
            for b in range(m):
                acc = complex(0.0, 0.0)
                for i in range(m):
                    acc += (complex(p[oVr + a * m + i], p[oVi + a * m + i]) * ee[i]) * complex(
                        p[oWr + i * m + b], p[oWi + i * m + b])
                E2[a, b] = acc.real
        return math.exp(-p[ok] * h), E2

    def put(out, a, v):
        """``out[a:a + len(v)] = v`` as a loop (numba's slice assignment adds a
        shape check whose error path took about 2.5 s of the compile)."""
        for i in range(v.shape[0]):
            out[a + i] = v[i]

    def core(z, y, t, p):
        k = p[ok]
        w = z[e:e + q]
        xi1, xi2 = z[0:m], z[m:m + q]
        ps1, ps2 = z[m + q:2 * m + q], z[2 * m + q:e]
        out = np.empty(r)
        f1 = mv(p, oL1, m, q, w)                                    # F1(omega, t), F2 of (2)
        f2 = mv(p, oL2, q, q, w)
        if has_psi:
            o = int(p[opsi])
            pv = psi(p[o:o + int(p[opsi + 1])], w, t)
            f1 = f1 + mv(p, oP, m, n, pv)
            f2 = f2 + mv(p, oN, q, n, pv)
        innov = mv(p, oH, m, q, w - xi2)                            # H (omega - xi2_hat)
        put(out, 0, mv(p, oA1, m, m, xi1) + f1)                     # (7) xi1_hat
        put(out, m, mv(p, oA2, q, m, xi1) - k * xi2 + f2)           # (7) xi2_hat (decision 1)
        put(out, m + q, -k * ps1 + innov)                           # (7) psi1
        put(out, 2 * m + q, mv(p, omA, m, m, ps2) + innov)          # (7) psi2, literal
        # (13) with decision 3's window h = min(tau, t - t0); psi(t - tau) is the past
        # the engine hands over after the parameters (x0 before t0 = psi(t0))
        b = p.shape[0] - r
        pd1, pd2 = p[b + m + q:b + 2 * m + q], p[b + 2 * m + q:b + e]
        tau = p[otau]
        h = min(tau, t - p[ot0])
        if h < tau:
            E1, E2 = decay(h, p)
            e2 = np.empty(m)
            for a in range(m):
                acc = 0.0
                for c in range(m):
                    acc += E2[a, c] * pd2[c]
                e2[a] = acc
        else:
            E1 = p[oE1]
            e2 = mv(p, oE2, m, m, pd2)
        v = E1 * pd1 - ps1 + ps2 - e2
        xe = xi1 + mv(p, oR, m, q, y - xi2) + mv(p, oSi, m, m, v)     # (13)
        put(out, e, mv(p, oA2, q, m, xe) - k * w + f2)              # (39) omega
        out[e + q] = 1.0                                            # sigma
        out[e + q + 1] = 0.0                                        # kappa
        return out

    if xi2:
        def flow(z, u, t, j, p):                                    # (13) with xi_2 (oracle)
            return core(z, u[q:2 * q], t, p)
    else:
        def flow(z, u, t, j, p):                # (13) with omega: the input is not read
            return core(z, z[e:e + q], t, p)

    def jump(z, u, t, j, p):                                        # a sample, (39)
        out = z.copy()
        for c in range(q):
            out[e + c] = u[c]
        out[e + q] = 0.0
        out[e + q + 1] = z[e + q + 1] + 1.0
        return out

    def jump_guard(z, u, t, j, p):
        if sampling != "instants":                  # sigma - period, or sigma - T_low (36)
            return z[e + q] - p[os_]
        kap = math.floor(z[e + q + 1] + 0.5)
        if kap >= int(p[os_]):
            return -1.0
        return t - p[int(p[os_ + 1]) + kap]

    def flow_guard(z, u, t, j, p):                                  # gaps: C = {sigma <= T_bar}
        return p[os_ + 1] - z[e + q]

    return flow, jump, jump_guard, (flow_guard if sampling == "gaps" else None)


def _probe_shape(name, call, shape, what):
    """Call a user map once (at y = 0, t = 0) and check its output size.

    A map that raises is not judged here.
    """
    try:
        v = np.asarray(call(), dtype=float)
    except Exception:       # noqa: BLE001 -- the map may be undefined at the probe point; the run will tell
        return
    if v.size != int(np.prod(shape)):
        raise ValueError(f"{name}(y, t) must return shape {shape} {what}, got shape {v.shape}")


class _ObserverBase(hs.HybridSystem):
    """Shared checks, slicing and the extension (7) in either realisation of psi_2.

    Layout of the extension: ``(xi1_hat, xi2_hat, psi1, psi2)`` (literal) or
    ``(xi1_hat, xi2_hat, psi1, p, phi, P, rho)`` (reset; module docstring).
    """

    def __init__(self, design, F1, F2, realisation="literal"):
        if not isinstance(design, GramianDesign):
            raise TypeError(f"design must be a GramianDesign, got {type(design).__name__}")
        for name, F in (("F1", F1), ("F2", F2)):
            if not callable(F):
                raise TypeError(f"{name} must be callable (y, t) -> array, got {type(F).__name__}")
        if realisation not in REALISATIONS:
            raise ValueError(f"realisation must be one of {REALISATIONS}, got {realisation!r}")
        self.design = design
        self.F1, self.F2 = F1, F2
        form = getattr(F1, "__self__", None)
        if getattr(F2, "__self__", None) is form and hasattr(form, "F12"):
            self._F12 = form.F12           # an ObserverForm's F1, F2: one Psi per evaluation
        else:
            def F12(y, t):
                return (np.asarray(F1(y, t), dtype=float).reshape(design.m),
                        np.asarray(F2(y, t), dtype=float).reshape(design.q))
            self._F12 = F12
        self.realisation = realisation
        # maps over batches where F1, F2 are an ObserverForm's whose Psi takes the last axis
        self._batch = form is not None and hasattr(form, "F12") and (
            form.Psi is None or bool(getattr(form.Psi, "batch", False)))
        m, q = design.m, design.q
        # dimensions agree at construction, not as a broadcast error inside a run
        for name, F, dim in (("F1", F1, m), ("F2", F2, q)):
            _probe_shape(name, lambda F=F: F(np.zeros(q), 0.0), (dim,),
                         f"(n - q = {m} unmeasured states)" if name == "F1"
                         else f"(q = {q} outputs)")
        self.sl_xi1 = slice(0, m)
        self.sl_xi2 = slice(m, m + q)
        self.sl_psi1 = slice(m + q, 2 * m + q)
        self.sl_psi2 = slice(2 * m + q, 3 * m + q)       # literal: psi2; reset: p
        if realisation == "reset":
            self.sl_p = self.sl_psi2
            self.sl_phi = slice(3 * m + q, 4 * m + q)
            self.sl_P = slice(4 * m + q, 5 * m + q)
            self.i_rho = 5 * m + q
            self.n_ext = 5 * m + q + 1
        else:
            self.n_ext = 3 * m + q
        self._mA2 = -design.A_psi2
        # a reset-interval end within this many seconds of rho = 0 or tau is treated as on
        # it (rho is the integrated timer: ~1e-15 off the located reset time)
        self._rho_eps = 1e-12 * max(1.0, design.tau)

    def _extension_flow(self, z, t, y, out):
        """Flows of the extension (7) with measurement y (Y, or omega in (39)), into out.

        Returns F2(y, t) (the flow of omega in (39) needs it too). On the last
        axis: z (N, r), y (N, q), t (N,) give a batch's flows.
        """
        d = self.design
        xi1, xi2 = z[..., self.sl_xi1], z[..., self.sl_xi2]
        innov = (y - xi2) @ d.H.T
        f1, f2 = self._F12(y, t)
        out[..., self.sl_xi1] = xi1 @ d.A1.T + f1                                   # (7) xi1_hat
        out[..., self.sl_xi2] = xi1 @ d.A2.T - d.k * xi2 + f2                       # (7) xi2_hat
        out[..., self.sl_psi1] = -d.k * z[..., self.sl_psi1] + innov                # (7) psi1
        out[..., self.sl_psi2] = z[..., self.sl_psi2] @ self._mA2.T + innov         # (7) psi2 / p
        if self.realisation == "reset":
            out[..., self.sl_phi] = z[..., self.sl_phi] @ self._mA2.T               # phi
            out[..., self.sl_P] = 0.0                                               # P
            out[..., self.i_rho] = 1.0                                              # rho
        return f2

    def _reset_guard(self, z):
        """rho - tau: >= 0 when the reset realisation's timer is due (a batch: (N,))."""
        return z[..., self.i_rho] - self.design.tau

    def _reset(self, z):
        """The reset realisation's jump: P+ = phi+ = p, p+ = 0, rho+ = 0 (in place)."""
        p = z[..., self.sl_p].copy()
        z[..., self.sl_P] = p
        z[..., self.sl_phi] = p
        z[..., self.sl_p] = 0.0
        z[..., self.i_rho] = 0.0
        return z

    def _initial(self, xi1_hat0, xi2_hat0, psi10, psi20):
        d = self.design
        head = [np.zeros(d.m) if xi1_hat0 is None else vector("xi1_hat0", xi1_hat0, d.m),
                np.zeros(d.q) if xi2_hat0 is None else vector("xi2_hat0", xi2_hat0, d.q),
                np.zeros(d.m) if psi10 is None else vector("psi1_0", psi10, d.m)]
        if self.realisation == "reset":
            if psi20 is not None:
                raise ValueError("psi2_0 must be None with realisation='reset': p starts at 0 "
                                 "(by decision 3 the estimate (13) never depends on psi_2(t0))")
            return np.concatenate(head + [np.zeros(3 * d.m), [0.0]])
        return np.concatenate(head + [np.zeros(d.m) if psi20 is None
                                      else vector("psi2_0", psi20, d.m)])

    def _estimate(self, z, t, y, read):
        r"""xi_e of (13) at time t from the state z, the signal y and the past.

        ``read(s)`` returns the observer's state at a past time s (the run's
        history during a run, the arc afterwards). The window is
        ``h = min(tau, t - t0)`` (decision 3). Literal realisation: (13) as
        printed, psi at t - h. Reset realisation: psi_2(t) - e^{-(A1^T+2kI)h}
        psi_2(t-h) is replaced by I_2 = p + phi - e^{-(A1^T+2kI) tau} p(t - tau)
        (module docstring), with p(t - tau) read in the previous reset
        interval.
        """
        d = self.design
        psi_del, h = _delayed(d, t, self.t0, read)                          # psi(t - h)
        if self.realisation == "literal":
            return d.xi_e(z[self.sl_xi1], z[self.sl_xi2], z[self.sl_psi1], z[self.sl_psi2],
                          psi_del[self.sl_psi1], psi_del[self.sl_psi2], y, h=h)   # (13)
        rho = z[self.i_rho]
        if t - rho - self.t0 < 0.5 * d.tau:
            p_del = np.zeros(d.m)               # first interval: window [t0, t], p(t0) = 0
        elif rho >= d.tau - self._rho_eps:
            p_del = z[self.sl_P]                # t - tau is the last reset: p(t_r^-) = P
        elif rho <= self._rho_eps:
            p_del = np.zeros(d.m)               # t - tau is the previous reset: p = 0 there
        else:
            p_del = psi_del[self.sl_p]          # inside the previous reset interval
        I2 = z[self.sl_p] + z[self.sl_phi] - d.E2 @ p_del                   # (53) window
        return d.xi_e(z[self.sl_xi1], z[self.sl_xi2], z[self.sl_psi1], I2,
                      psi_del[self.sl_psi1], np.zeros(d.m), y, h=h)        # (13)


def _delayed(design, t, t0, psi_at):
    """psi_1, psi_2 at t - h and the window h (decision 3: h = min(tau, t - t0))."""
    h = min(design.tau, t - t0)
    if h < design.tau:
        return psi_at(t0), h
    return psi_at(t - design.tau), h


class GramianObserver(_ObserverBase):
    r"""The dynamic extension (7) for continuous measurements Y (Theorem 1).

    State ``z = (xi1_hat, xi2_hat, psi1, psi2)`` of length ``3(n-q) + q``
    (``realisation="literal"``), or ``(xi1_hat, xi2_hat, psi1, p, phi, P,
    rho)`` of length ``5(n-q) + q + 1`` (``"reset"``: jumps every tau, see
    the module docstring); input ``u = Y`` (q,).

    .. math::
        \dot{\hat\xi}_1 = A_1\hat\xi_1 + F_1(Y, t),\quad
        \dot{\hat\xi}_2 = A_2\hat\xi_1 - k\hat\xi_2 + F_2(Y, t),\\
        \dot\psi_1 = -k\psi_1 + H(Y - \hat\xi_2),\quad
        \dot\psi_2 = -(A_1^\top + 2kI)\psi_2 + H(Y - \hat\xi_2).

    The estimate (13) reads psi at t - tau and Y(t); it is evaluated along
    a finished run by :meth:`estimate` (the engine's output map may not
    depend on the input).

    Parameters
    ----------
    design : GramianDesign
    F1, F2 : callable
        ``F1(y, t) -> (n-q,)``, ``F2(y, t) -> (q,)`` of (2).
    t0 : float
        Start of the runs (for the history rule before t0 + tau).
    realisation : {"literal", "reset"}
        How psi_2 of (7) is carried (module docstring).

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> from observers import gramian_delay as gd
    >>> ex = gd.dc_motor(100.0, 0.1, disturbed=False)
    >>> obs = ex.continuous_observer()                     # (7)
    >>> arc = gd.simulate(obs, ex.chi0, None, t_max=0.3)
    >>> bool(np.abs(gd.errors(arc, obs).e[arc.t >= 0.1]).max() < 1e-8)   # Theorem 1
    True

    References
    ----------
    Mazenc & Malisoff (2022), eqs. (7), (13), Theorem 1.
    """

    def __init__(self, design, F1, F2, *, t0=0.0, realisation="literal"):
        super().__init__(design, F1, F2, realisation)
        self.t0 = float(t0)
        self.state_dim = self.n_ext
        self.input_dim = design.q
        self.vectorized = self._batch                      # maps over (N, r) batches too
        if realisation == "reset":
            self.jump_guard = self._jump_guard_reset       # D = {rho >= tau}; literal: D empty

    def flow_map(self, z, t, j, u):
        out = np.empty(np.shape(z))
        self._extension_flow(z, t, np.asarray(u, dtype=float), out)
        return out

    def _jump_guard_reset(self, z, t, j, u):
        return self._reset_guard(z)

    def jump_map(self, z, t, j, u):
        """The reset realisation's jump (the literal one never jumps: D is empty)."""
        if self.realisation == "literal":
            return np.array(z, dtype=float)
        return self._reset(np.array(z, dtype=float))

    def initial_state(self, xi1_hat0=None, xi2_hat0=None, psi1_0=None, psi2_0=None):
        """The observer's initial state (zeros where not given)."""
        return self._initial(xi1_hat0, xi2_hat0, psi1_0, psi2_0)

    def estimate(self, arc, y, *, name=None):
        r"""xi_e (13) at every sample of ``arc``; time-major (N, n-q).

        Parameters
        ----------
        arc : HybridArc
            The run (of this observer alone, or of an interconnection with
            ``name`` naming this observer). Run it with ``dense=True``: the
            values at t - tau are then read from the solver's dense output
            (exact to the integrator), else they are interpolated.
        y : (N, q) array_like or callable
            The measured signal at the samples: Y(t) (implementable), or
            xi_2(t) (the paper's (13)). A callable is ``(t) -> (q,)``.
        name : str, optional
            The observer's name in an interconnection.
        """
        return estimate_along(self, arc, y, name=name)


class SampledGramianObserver(_ObserverBase):
    r"""The observer (39) for measurements sampled at t_0 < t_1 < ... (Theorem 2).

    State ``z = (extension, omega, sigma, kappa)``: (7)'s extension (either
    realisation of psi_2) driven by omega instead of Y, omega (q,), a timer
    sigma (time since the last sample) and a sample counter kappa. Input
    ``u = Y`` (q,) (or ``(Y, xi2)`` (2q,) with ``estimate="xi2"``), read at
    the jumps only. Flow (between samples), (39):

    .. math::
        \dot{\hat\xi}_1 = A_1\hat\xi_1 + F_1(\omega, t),\quad
        \dot{\hat\xi}_2 = A_2\hat\xi_1 - k\hat\xi_2 + F_2(\omega, t),\\
        \dot\psi_i = \dots + H(\omega - \hat\xi_2),\quad
        \dot\omega = A_2\xi_e(t) - k\omega + F_2(\omega, t),

    with xi_e of (13) reading psi at t - tau through the run's history (a
    delay equation; ``max_step = tau``). Jump (a sample): omega^+ = Y,
    sigma^+ = 0, kappa^+ = kappa + 1; with ``realisation="reset"`` also the
    reset of p every tau (the guard is the larger of the two).

    Decisions (package docstring): the xi2_hat flow uses ``A2 xi1_hat`` (the
    printed ``A2 xi2_hat`` of (39) is a typo); ``estimate="omega"`` puts
    omega(t) in place of the unmeasured xi_2(t) in (13).

    Parameters
    ----------
    design : GramianDesign
    F1, F2 : callable
        As in (2).
    period : float, optional
        Periodic sampling by the timer: D = {sigma >= period}.
    instants : (K,) array_like, optional
        Increasing sampling instants (e.g. :func:`sampling_instants`):
        D = {t >= instants[kappa]}.
    gaps : (float, float), optional
        ``(T_low, T_bar)`` of (36): every gap between samples in [T_low,
        T_bar], as a hybrid inclusion: C = {sigma <= T_bar}, D = {sigma >=
        T_low}. :func:`hybridsim.simulate` samples every T_low (``priority``
        "jumps"), or after a random dwell in C ∩ D (``dwell=``);
        :func:`hybridsim.explore` follows every gap of a dwell grid
        (Theorem 2 is a statement about all of them). Exactly one of
        period, instants, gaps; gaps with ``realisation="literal"`` only.
    estimate : {"omega", "xi2"}
    t0 : float
        Start of the runs (history rule before t0 + tau).
    realisation : {"literal", "reset"}
        How psi_2 is carried (module docstring).

    Examples
    --------
    >>> import numpy as np
    >>> from observers import gramian_delay as gd
    >>> ex = gd.dc_motor(100.0, 0.1, disturbed=False)
    >>> obs = ex.sampled_observer(period=0.005)             # (39), omega in (13)
    >>> arc = gd.simulate(obs, ex.chi0, None, t_max=0.5)
    >>> bool(np.abs(gd.errors(arc, obs).e[arc.t >= 0.4]).max() < 1e-6)
    True

    References
    ----------
    Mazenc & Malisoff (2022), eqs. (36)-(39), Theorem 2.
    """

    def __init__(self, design, F1, F2, *, period=None, instants=None, gaps=None,
                 estimate="omega", t0=0.0, realisation="literal"):
        super().__init__(design, F1, F2, realisation)
        if sum(v is not None for v in (period, instants, gaps)) != 1:
            raise ValueError("give exactly one of period, instants and gaps")
        self.gaps = None
        if gaps is not None:
            try:
                lo, hi = (float(g) for g in gaps)
            except (TypeError, ValueError):
                raise ValueError(f"gaps must be a pair (T_low, T_bar) of (36), got "
                                 f"{gaps!r}") from None
            if not (np.isfinite(hi) and 0.0 < lo < hi):
                raise ValueError(f"gaps must satisfy 0 < T_low < T_bar < inf (36), got "
                                 f"({lo}, {hi})")
            if realisation != "literal":
                raise ValueError("gaps needs realisation='literal': the reset realisation's "
                                 "resets are jumps too, and inside the window [T_low, T_bar] "
                                 "one would take a sample that the sequence did not choose")
            self.gaps = (lo, hi)
            self.period = self.instants = None
            self.flow_guard = self._gap_flow_guard                  # C = {sigma <= T_bar}
        elif period is not None:
            self.period = scalar("period", period, positive=True)
            self.instants = None
        else:
            ins = np.asarray(instants, dtype=float).reshape(-1)
            if ins.size == 0 or not np.all(np.isfinite(ins)):
                raise ValueError("instants must be a non-empty finite 1-D array")
            if np.any(np.diff(ins) <= 0):
                raise ValueError("instants must be strictly increasing")
            self.period, self.instants = None, ins
        if estimate not in ("omega", "xi2"):
            raise ValueError(f"estimate must be 'omega' or 'xi2', got {estimate!r}")
        self.estimate_source = estimate
        q = design.q
        e = self.n_ext
        self.t0 = float(t0)
        self.sl_omega = slice(e, e + q)
        self.i_sigma = e + q
        self.i_kappa = self.i_sigma + 1
        self.state_dim = e + q + 2
        self.input_dim = q if estimate == "omega" else 2 * q
        self.max_step = design.tau
        self.needs_history = True
        # psi' jumps with omega at the samples, so psi(t - tau) has kinks at t_k + tau
        self.delays = (design.tau,)
        # maps over (N, r) batches (hs.simulate_many, the past read by hs.BatchHistory)
        self.vectorized = self._batch and realisation == "literal"

    def initial_state(self, xi1_hat0=None, xi2_hat0=None, psi1_0=None, psi2_0=None,
                      omega0=None):
        """Initial state; the timer/counter are set so that a sample is taken at t0."""
        q = self.design.q
        w = np.zeros(q) if omega0 is None else vector("omega0", omega0, q)
        sigma0 = (self.period if self.period is not None
                  else self.gaps[1] if self.gaps is not None else 0.0)
        return np.concatenate([self._initial(xi1_hat0, xi2_hat0, psi1_0, psi2_0), w,
                               [sigma0, 0.0]])

    def _xi_e_now(self, z, t, u):
        y = z[self.sl_omega] if self.estimate_source == "omega" else np.asarray(u)[self.design.q:]
        return self._estimate(z, t, y, self.history)

    def _xi_e_batch(self, z, t, u):
        """xi_e of (13) for a batch: z (N, r), t (N,), the rows' past from the run's
        BatchHistory (decision 3's window h = min(tau, t - t0) per row)."""
        d = self.design
        y = z[:, self.sl_omega] if self.estimate_source == "omega" else u[:, d.q:]
        t = np.broadcast_to(np.asarray(t, dtype=float), (len(z),))
        full = t - self.t0 >= d.tau
        past = self.history(np.where(full, t - d.tau, self.t0))          # psi(t - h)
        args = (z[:, self.sl_xi1], z[:, self.sl_xi2], z[:, self.sl_psi1], z[:, self.sl_psi2],
                past[:, self.sl_psi1], past[:, self.sl_psi2], y)
        out = np.empty((len(z), d.m))
        if full.any():
            out[full] = d.xi_e(*(a[full] for a in args))                       # (13)
        if not full.all():                      # before t0 + tau: each row's own window,
            early = np.flatnonzero(~full)       # one decay per window length (rows at one t)
            hs_, which = np.unique(t[early] - self.t0, return_inverse=True)
            for g, h in enumerate(hs_):
                rows = early[which == g]
                out[rows] = d.xi_e(*(a[rows] for a in args), h=h)
        return out

    def _xi_e(self, z, t, u):
        """xi_e of (13) during a run: one state, or a batch (N, r) read through the
        run's BatchHistory (:meth:`_xi_e_batch`)."""
        # kept apart: a batch reads its past in one call of a BatchHistory and each
        # row before t0 + tau has its own window h (one matrix exponential per row),
        # while one state's estimate (_estimate) also serves the reset realisation
        # and estimate_along on a finished arc
        return self._xi_e_batch(z, t, u) if np.ndim(z) == 2 else self._xi_e_now(z, t, u)

    def flow_map(self, z, t, j, u):
        """(39) between samples, on the last axis (z (r,) or a batch (N, r))."""
        d = self.design
        w = z[..., self.sl_omega]
        out = np.empty(np.shape(z))
        f2 = self._extension_flow(z, t, w, out)                                     # F2(omega, t)
        xe = self._xi_e(z, t, u)
        out[..., self.sl_omega] = xe @ d.A2.T - d.k * w + f2                        # (39)
        out[..., self.i_sigma] = 1.0
        out[..., self.i_kappa] = 0.0
        return out

    def _gap_flow_guard(self, z, t, j, u):
        return self.gaps[1] - z[..., self.i_sigma]

    def _sample_guard(self, z, t):
        if self.period is not None:
            return z[..., self.i_sigma] - self.period
        if self.gaps is not None:
            return z[..., self.i_sigma] - self.gaps[0]
        kap = np.rint(z[..., self.i_kappa]).astype(np.int64)
        ins = self.instants[np.minimum(kap, len(self.instants) - 1)]
        return np.where(kap >= len(self.instants), -1.0, t - ins)

    def jump_guard(self, z, t, j, u):
        g = self._sample_guard(z, t)
        if self.realisation == "reset":
            g = max(g, self._reset_guard(z))
        return g

    def jump_map(self, z, t, j, u):
        """A sample (39), on the last axis; the reset realisation (one state only: it is
        not vectorized) resets p first and samples only when the sample is due too."""
        z = np.array(z, dtype=float)
        if self.realisation == "reset" and self._reset_guard(z) >= 0:
            self._reset(z)
            if self._sample_guard(z, t) < 0:
                return z
        z[..., self.sl_omega] = np.asarray(u, dtype=float)[..., :self.design.q]  # omega(t_j) = Y
        z[..., self.i_sigma] = 0.0
        z[..., self.i_kappa] += 1.0
        return z

    def compiled_refusal(self):
        """Why (39) has no compiled form here (a sentence naming the argument), or None."""
        if self.realisation != "literal":
            return ("realisation='reset' has no compiled form (its reading of p(t - tau) "
                    "depends on the reset interval); use realisation='literal'")
        form = getattr(self.F1, "__self__", None)
        if not isinstance(form, ObserverForm) or getattr(self.F2, "__self__", None) is not form:
            return ("its F1, F2 are not an ObserverForm's (the compiled form reads F1, F2 of "
                    "(2) from the form's matrices and its Psi's compiled form)")
        why = None if form.Psi is None else _psi_refusal(form.Psi)
        if form.Psi is not None and not why:
            from hybridsim._source import SourceRefusal, plan_function
            try:
                plan_function(form.Psi)             # its code, rewritten (no numba)
            except SourceRefusal as e:
                why = f"its code cannot be rewritten for numba: {e}"
        if why:
            return f"the Psi of its form is a Python callable that does not run compiled: {why}"
        if self.design._psi2_modes is None:
            return ("the early window of (13) (decision 3) needs e^{-(A1^T + 2kI) h} for "
                    "h < tau, computed from the eigen-decomposition of A1^T + 2kI, which is "
                    "ill conditioned for this design (cond > 1e6)")
        return None

    # A compiled twin of flow_map, jump_map and jump_guard, kept (issue 42's named
    # exception): the rewrite from source cannot take (39)'s maps as written (it
    # follows the design's matrices and the form's bound F12, as for (7)), because
    # 1. (its refusal today) _xi_e_batch reads self.history(np.where(full, t - tau,
    #    t0)), not at t - tau;
    # 2. (13) reads the past through self._estimate(z, t, y, self.history), the
    #    history passed as a value (to _delayed), where the rewrite takes calls
    #    self.history(t - tau) in the flow map only;
    # 3. before t0 + tau, (13) reads psi(t0), a fixed time, not t - tau (on the
    #    kernel that is the prehistory x0, right for runs that start at t0);
    # 4. the early window's e^{-(A1^T + 2kI) h} is GramianDesign.decay: complex
    #    eigenmodes, or scipy's expm where they are ill conditioned;
    # 5. flow_map has a batch branch (_xi_e: rows read from a BatchHistory, each
    #    row before t0 + tau with its own window) for the vectorized path.
    # Rewriting them for numba would move the Python path's arithmetic, and with
    # it the pinned claims ((13) multiplies an ulp of omega's flow by |S^-1| ~ 1e5).
    # The twin calls the form's Psi (and the control u in it) as written, rewritten
    # from source (compiled_function): only (7), (13) and (39) are written twice.
    def compiled_component(self):
        r"""(39) in compiled form (``backend="compiled"``, realisation "literal").

        The same flow (7) with omega in place of Y, (39) for omega with xi_e of
        (13), and the samples of (39) (``period``, ``instants`` or ``gaps`` of
        (36)); the design's matrices (A1, A2, k, H, R, S^{-1}, E1, E2, the
        modes of A1^T + 2kI for decision 3's early window) and F1, F2 of (2)
        (the form's M12, M22 + kI, P, N and Psi's compiled form) are in the
        parameters. The flow reads psi(t - tau) from the past state the
        engine hands it (``delays=(tau,)``: :class:`hybridsim.compiled.Component`);
        before t0 + tau that is the constant x0 (the compiled path's
        prehistory), whose psi is psi(t0), the value (13) reads there
        (decision 3), for runs starting at the observer's ``t0`` or later.

        Raises
        ------
        TypeError
            Naming what has no compiled form (:meth:`compiled_refusal`).

        References
        ----------
        Mazenc & Malisoff (2022), eqs. (7), (13), (36)-(39).
        """
        from hybridsim.compiled import Component
        why = self.compiled_refusal()
        if why:
            raise TypeError(f"backend='compiled': SampledGramianObserver cannot run "
                            f"compiled: {why}")
        d = self.design
        form = self.F1.__self__
        m, q, n = d.m, d.q, form.n
        V, w, Vi = d._psi2_modes

        def re_im(a):
            a = np.asarray(a)
            return [a.real.ravel(), (a.imag.ravel() if np.iscomplexobj(a)
                                     else np.zeros(a.size))]
        L1, L2 = form._linear
        head = [d.A1.ravel(), d.A2.ravel(), [d.k], d.H.ravel(), self._mA2.ravel(),
                d.R.ravel(), d.S_inv.ravel(), [d.E1], d.E2.ravel(), [d.tau, self.t0],
                *re_im(V), *re_im(w), *re_im(Vi), L1.ravel(), L2.ravel(), form.P.ravel(),
                form.N.ravel()]
        size = sum(np.size(a) for a in head) + 4
        fn, pp = None, np.zeros(0)
        if form.Psi is not None:        # Psi's own code, rewritten (its numbers in pp)
            from hybridsim.compiled._from_source import compiled_function
            fn, pp = compiled_function(form.Psi)
        if self.period is not None:
            sampling, samp = "period", [self.period, 0.0]
        elif self.gaps is not None:
            sampling, samp = "gaps", list(self.gaps)
        else:
            sampling, samp = "instants", [len(self.instants), size + pp.size]
        params = np.concatenate([np.concatenate([np.ravel(a) for a in head]), samp,
                                 [size, pp.size], pp]
                                + ([self.instants] if sampling == "instants" else []))
        flow, jump, guard, fguard = _sampled_maps(m, q, n, fn, sampling,
                                                  self.estimate_source == "xi2")
        return Component(state_dim=self.state_dim, input_dim=self.input_dim, flow_map=flow,
                         jump_map=jump, jump_guard=guard, flow_guard=fguard, params=params,
                         delays=(d.tau,))

    def estimate(self, arc, *, y=None, name=None):
        r"""xi_e (13) at every sample of ``arc`` as the observer used it.

        With ``estimate="omega"`` the signal in (13) is the arc's omega
        (default ``y``); pass ``y`` (e.g. the true xi_2) to evaluate (13)
        with another signal. Run with ``dense=True`` for exact delayed values.
        """
        if y is None:
            if self.estimate_source != "omega":
                raise ValueError("y must be given (the xi_2 samples) when estimate='xi2'")
            arc_o = arc.component(name) if name is not None else arc
            y = arc_o.x[:, self.sl_omega]
        return estimate_along(self, arc, y, name=name)


def estimate_along(observer, arc, y, *, name=None):
    r"""Evaluate xi_e (13) along a finished run of a Gramian observer.

    Parameters
    ----------
    observer : GramianObserver or SampledGramianObserver
    arc : HybridArc
        The run; with ``name``, an interconnection's run and the observer's
        component name.
    y : (N, q) array_like or callable t -> (q,)
        The signal that stands for xi_2(t) in (13), at the arc's samples.
    name : str, optional

    Returns
    -------
    (N, n-q) array, time-major.

    Notes
    -----
    psi at t - tau is read with ``arc.at`` (the solver's dense output when
    the run kept it). Before t0 + tau the window is truncated to [t0, t]
    (decision 3).

    Examples
    --------
    >>> import numpy as np
    >>> from observers import gramian_delay as gd
    >>> ex = gd.dc_motor(150.0, 0.1, disturbed=False)
    >>> obs = ex.continuous_observer()
    >>> arc = gd.simulate(obs, ex.chi0, None, t_max=0.2)
    >>> xe = gd.estimate_along(obs, arc, arc.outputs("plant"), name="observer")
    >>> xe.shape == (len(arc.t), 2)
    True

    References
    ----------
    Mazenc & Malisoff (2022), eq. (13).
    """
    if not isinstance(observer, _ObserverBase):
        raise TypeError(f"observer must be a Gramian observer, got {type(observer).__name__}")
    d = observer.design
    if name is not None:
        sl = arc.components[name]
        Z = arc.x[:, sl]

        def read(s):
            return arc.at(s)[sl]
    else:
        Z = arc.x
        read = arc.at
    if Z.shape[1] != observer.state_dim:
        raise ValueError(f"arc must hold the observer's state of length {observer.state_dim}, "
                         f"got {Z.shape[1]} (pass name= for an interconnection)")
    if callable(y):
        Y = np.array([np.asarray(y(t), dtype=float).reshape(d.q) for t in arc.t])
    else:
        Y = np.asarray(y, dtype=float)
        if Y.shape != (len(arc.t), d.q):
            raise ValueError(f"y must have shape ({len(arc.t)}, {d.q}), got {Y.shape}")
    out = np.empty((len(arc.t), d.m))
    for i, t in enumerate(arc.t):
        out[i] = observer._estimate(Z[i], t, Y[i], read)
    return out
