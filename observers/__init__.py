"""Finite-time state observers from five control papers, built on :mod:`hybridsim`.

Papers
------
li_sanfelice   002  H_n, H_c, H_pc resetting observers (Li & Sanfelice)
gramian_delay  004  fixed-time Gramian observers with one delay (Mazenc & Malisoff, LCSYS 2022)
time_varying   001  reduced-order finite-time observers (Mazenc, Ahmed & Malisoff, CDC 2018)
dynamic_gain   000  robust finite-time observer with dynamic gain (Nekhoroshikh et al., CDC 2022)
distributed    003  finite-time distributed observer over a digraph (Silm et al., SCL 2020)
lmi                 the LMIs of the dynamic-gain and distributed designs (cvxpy, optional extra)

The calling pattern
-------------------
Every paper is a package ``observers/<name>/`` of the same shape, so that
learning one teaches the others::

    __init__.py   PAPER, ERRATA, DECISIONS, CLAIMS and the public names
    design.py     the paper's design computations and bounds (pure numpy/scipy)
    systems.py    the hybrid systems: observer(s) and plant(s) as hs.HybridSystem
    example.py    the paper's example(s) and how a run is made and read
    figures.py    reproduce(outdir): the paper's figures, each with a caption
    claims.py     CLAIMS: every quantitative statement, with its number

1. **Design** from the paper's data: a ``design(...)`` function (or a
   ``Design`` class) validates its input at construction (dimensions,
   observability, the paper's assumptions, each failure naming the argument
   and the reason) and carries the paper's quantities (gains, T, Λ, S...).
2. **Observer** as a :class:`hybridsim.HybridSystem` built from a design;
   its input is the measured output.
3. **Run** with its plant: ``simulate(observer, x0, xhat0, *, t_max, noise=None,
   seed=None, **simulate_kwargs)`` returns the :class:`hybridsim.HybridArc`
   of the interconnection, with components ``"plant"`` and ``"observer"``;
   ``simulate_kwargs`` go to :func:`hybridsim.simulate`.
4. **Errors**: ``errors(arc, observer)`` returns the estimation error at
   the arc's samples, shape (N, n) (or a dict of named error signals with
   the main one under ``"e"`` where a paper has several).
5. **Seeds**: every function that draws random numbers takes ``seed=``
   (an int or a numpy Generator); nothing is random without it.
6. **Figures**: ``reproduce(outdir) -> list[pathlib.Path]`` writes PNGs, each
   with a ``.txt`` caption beside it, using :mod:`hybridsim`'s plots.
7. **Claims**: ``CLAIMS``, a list of :class:`observers.claims.Claim`, one per
   quantitative statement (the paper's value, ours, the tolerance and why,
   the verdict); the tests pin each one and the main job writes them to
   ``claims.csv`` and ``index.html``.

What a paper needs beyond this is an addition (extra keywords, extra
functions), not a variation. Input checks use :mod:`observers._common`, and
the engine is imported one way: ``import hybridsim as hs``.
"""
