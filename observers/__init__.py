"""Finite-time state observers from five control papers, built on :mod:`hybridsim`.

Papers
------
li_sanfelice   002  H_n, H_c, H_pc resetting observers (Li & Sanfelice)
gramian_delay  004  fixed-time Gramian observers with one delay (Mazenc & Malisoff, LCSYS 2022)
time_varying   001  reduced-order finite-time observers (Mazenc, Ahmed & Malisoff, CDC 2018)
dynamic_gain   000  robust finite-time observer with dynamic gain (Nekhoroshikh et al., CDC 2022)
distributed    003  finite-time distributed observer over a digraph (Silm et al., SCL 2020)
lmi                 the LMIs of the dynamic-gain and distributed designs (cvxpy, optional extra)

The contract
------------
Every paper is a package ``observers/<name>/`` of the same shape, so that
learning one teaches the others; the contract is written in code in
:mod:`observers._common` (:data:`~observers._common.CONTRACT`) and checked
for all five by ``tests/papers/test_contract.py``::

    __init__.py   PAPER, ERRATA, DECISIONS; __all__ the public surface (at most 15 names:
                  the contract's, the paper's observer and design); the rest is
                  imported from its file, whose __all__ lists it
    design.py     the paper's formulas, design computations and bounds (numpy/scipy)
    systems.py    every hybrid system: observer(s) and plant(s) as hs.HybridSystem
    example.py    the paper's example data, simulate() and errors()
    figures.py    FIGURES (each figure's numbers, then its drawing), reproduce(),
                  NOT_REPRODUCED
    claims.py     CLAIMS: every quantitative statement, with its number
    falsification.py  PROBLEMS: the quantified statements as searches for
                  counterexamples (observers.falsification)

Imports run downward (design, systems, example, figures, claims, falsification).

1. **Design** from the paper's data: a ``design(...)`` function (or a
   ``Design`` class) validates its input at construction (dimensions,
   observability, the paper's assumptions, each failure naming the argument
   and the reason) and carries the paper's quantities (gains, T, Λ, S...).
2. **Observer** as a :class:`hybridsim.HybridSystem` built from a design;
   its input is the measured output.
3. **Run** with its plant: ``simulate(observer, x0, xhat0=None, *, t_max,
   noise=None, seed=None, **simulate_kwargs)`` returns the
   :class:`hybridsim.HybridArc` of the interconnection;
   ``simulate_kwargs`` go to :func:`hybridsim.simulate`.
4. **Errors**: ``errors(arc, observer)`` returns an
   :class:`observers._common.Errors`, a read-only mapping of the paper's
   named error signals at the arc's samples, the main one as ``.e`` (shape
   (N, k)), with the samples' ``t`` and ``j``.
5. **Seeds**: every function that draws random numbers takes ``seed=``
   (an int or a numpy Generator); nothing is random without it.
6. **Figures**: ``FIGURES``, a list of :class:`observers._common.Figure`:
   ``data()`` computes a figure's numbers (cached, so the claims read the
   same runs), ``draw(data)`` draws them, ``caption(data)`` says what they
   show; ``reproduce(outdir) -> list[pathlib.Path]`` writes each PNG with
   its ``.txt`` caption. ``NOT_REPRODUCED`` maps a figure of the paper
   left out to the reason.
7. **Claims**: ``CLAIMS``, a list of :class:`observers.claims.Claim`, one per
   quantitative statement (the paper's value, ours, the tolerance and why,
   the verdict; one-sided where the paper states a bound); the tests pin
   each one and the main job writes them to ``claims.csv`` and
   ``index.html``.

Library code neither prints nor chooses a matplotlib backend: what a run
has to say goes to :mod:`logging` (logger ``observers.<name>...``), which
the main job records in its report. What a paper needs beyond this is an
addition (extra keywords, extra functions), not a variation. Input checks
use :mod:`observers._common`, and the engine is imported one way:
``import hybridsim as hs``.
"""
