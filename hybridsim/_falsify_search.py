"""The searches of :func:`hybridsim.falsification.falsify`: differential
evolution, CMA-ES, the seeded first population, the compass search and the
gradient refinement from the worst point.
"""
from __future__ import annotations

import math

import numpy as np


def _de(ev, space, popsize, seed, budget, rnd=0):
    from scipy.optimize import differential_evolution
    free = space.hi > space.lo
    if not np.any(free):                     # a single point
        ev(space.lo[None, :])
        return
    lo, hi = space.lo[free], space.hi[free]

    def full(Zf):                            # (k, n_free) -> (k, dim)
        Z = np.tile(space.lo, (Zf.shape[0], 1))
        Z[:, free] = Zf
        return Z

    npop = max(5, popsize)
    maxiter = max(0, (budget - npop) // npop)
    init = _seeded(ev, space, free, npop, np.random.default_rng(seed), extremes=rnd == 0)
    # the first population is run before scipy's solver is built (a claim the
    # first runs refute costs no solver setup); the solver's first call, on
    # this population, is answered from it
    first = [ev(full(init))]
    if ev.done:
        return
    ev.stages.append((ev.n, "differential evolution" + (f" (restart {rnd})" if rnd else "")))

    def f(Zt):                               # scipy passes (n_free, k)
        if first:
            return first.pop()
        return ev(full(np.asarray(Zt).T))

    differential_evolution(
        f, list(zip(lo, hi)), maxiter=maxiter, seed=seed, init=init,
        vectorized=True, updating="deferred", polish=False,
        tol=0.0, atol=0.0, callback=lambda *a, **k: ev.done)


def _cmaes(ev, space, popsize, seed):
    """CMA-ES (Hansen's (mu/mu_w, lambda) with his default parameters) over the
    free coordinates scaled to [0, 1], after a seeded first design
    (:func:`_seeded`, ``max(2 lambda, 2 n)`` points).

    The runs go coarse to fine: the space's signals on grids 4 and 2 times
    coarser (:meth:`Space.coarse`: a subset of the box, few coordinates, where
    a signal held at a bound over a long stretch is one coordinate at its
    bound; a third of the first design is drawn on the coarsest), then the
    space itself, each run from the best point so far (its least-squares
    image on the run's grid) with the last run's step (its sigma times the
    longest axis, in [0.02, 0.3]) and the shape of its distribution
    (:func:`_carried`: its covariance mapped onto the finer grid, the
    directions the coarser grid could not move in given a tenth of the
    longest axis). A run on a coarse grid stops after ``budget / (2 grids)``
    runs, and the space's own run after ``budget / grids``, so restarts are
    left a share; a coarse run stops sooner at its grid's own optimum (its
    best margin gained less than 1 % of the run's gain in the last 10 + 3 n
    / lambda generations), and hands on the worst point snapped to the
    box's bounds (:func:`_snap`, two runs). A run from the worst
    point that finds nothing better within those generations also ends.
    Then restarts go through the same chain of grids, the population
    doubled each cycle (IPOP): on the coarsest grid from the best of a
    fresh design there (2 n points), on each finer grid from the best point
    of this restart's chain with its last run's step and shape, with the
    same shares (after a run that found no ranking, a flat margin, the next
    grid starts afresh: a coarse one from a fresh design, the space's own
    from a uniform mean without a share), whenever a run converges, stalls, meets a flat margin or
    spends its share. A space without signals has one grid, its own: one
    run after the first design, then restarts from uniform means.
    """
    if not np.any(space.hi > space.lo):
        ev(space.lo[None, :])
        return
    rng = np.random.default_rng(seed)
    grids = []                               # (factor, E, lo, width, free), coarse first
    for factor in (1, 2, 4):
        E, clo, chi = space.coarse(factor) if factor > 1 else (None, space.lo, space.hi)
        cfree = chi > clo
        n = int(cfree.sum())
        if n and all(n < g[4].sum() for g in grids):  # fewer coordinates than the last
            grids.insert(0, (factor, E, clo, (chi - clo)[cfree], cfree))

    def mapping(E, clo, width, cfree):
        def full(U):                         # (k, n) in [0, 1] -> (k, dim)
            C = np.tile(clo, (U.shape[0], 1))
            C[:, cfree] = clo[cfree] + np.clip(U, 0.0, 1.0) * width
            return C if E is None else C @ E.T
        return full

    def image(z, E, clo, width, cfree):      # a point of the space on a grid, in [0, 1]
        c = z if E is None else np.linalg.lstsq(E, z, rcond=None)[0]
        return np.clip((c[cfree] - clo[cfree]) / width, 0.0, 1.0)

    free = space.hi > space.lo
    n = int(free.sum())
    lam = popsize if popsize is not None else 4 + int(3 * math.log(n))
    first = np.tile(space.lo, (max(5, 2 * max(2, lam), 2 * n), 1))
    first[:, free] = _seeded(ev, space, free, len(first), rng)
    def design(k, m):                        # a Latin hypercube, some coordinates at a bound
        U = (rng.permuted(np.tile(np.arange(k), (m, 1)), axis=1).T + rng.random((k, m))) / k
        at = rng.random(U.shape) < 0.25
        U[at] = rng.integers(0, 2, int(at.sum()))
        return U

    if grids[0][1] is not None:              # a third of the design on the coarsest grid
        k = len(first) // 3
        first[len(first) - k:] = mapping(*grids[0][1:])(design(k, grids[0][3].size))
        ev.stages.append((ev.n + len(first) - k, "the first population's points on the "
                          f"grid {grids[0][0]} times coarser"))
    ev(first)
    run, step, cov, chain = 0, 0.3, None, None
    while not ev.done:
        k = run % len(grids)
        cycle, (factor, E, clo, width, cfree) = run // len(grids), grids[k]
        # a finer grid goes on from its chain's best point, unless the chain
        # found no ranking (a flat margin): then it starts afresh
        chained = k > 0 and (cycle == 0 or chain is not None)
        lam = popsize if popsize is not None else 4 + int(3 * math.log(width.size))
        lam = max(2, lam) * 2 ** cycle
        if cycle == 0 and ev.best_z is not None:
            mean = image(ev.best_z, E, clo, width, cfree)
        elif k and chain is not None:        # a restart goes on from its own best point
            mean = image(chain[1], E, clo, width, cfree)
        elif E is not None:                  # a restart on a coarse grid: from the best
            U = design(2 * width.size, width.size)      # of a fresh design there
            ev.stages.append((ev.n, f"a fresh design on the grid {factor} times coarser"))
            full = mapping(E, clo, width, cfree)
            f = ev(full(U))
            if ev.done:
                return
            i = int(np.argmin(f))
            mean, chain = U[i], (float(f[i]), full(U[i:i + 1])[0])
        else:
            mean = rng.random(width.size)
        grid = "" if E is None else f", its signals on a grid {factor} times coarser"
        ev.stages.append((ev.n, f"CMA-ES, population {lam}{grid}"
                          + (f" (restart {run})" if run else "")))
        # each cycle's shares: budget / (2 grids) a coarse grid, budget / grids
        # the space's own from the last grid's worst point
        if E is not None:
            until = ev.n + ev.budget // (2 * len(grids))
        else:
            until = ev.n + ev.budget // len(grids) if chained else math.inf
        # a run from the last grid's worst point goes on with that run's step
        # and its distribution's shape, mapped onto this grid
        sigma, C0 = 0.3, None
        if chained:
            sigma = min(0.3, max(0.02, step))
            if cov is not None:
                C0 = _carried(cov, grids[k - 1], grids[k])
        step, cov, rbest = _cma_run(ev, mapping(E, clo, width, cfree), mean, sigma, lam, rng,
                                    until, handoff=E is not None, stuck=chained, C0=C0)
        if cycle and rbest is None:
            chain = None
        elif cycle and (chain is None or rbest[0] < chain[0]):
            chain = rbest
        if E is not None and not ev.done:
            snapped = _snap(ev, space, ev.best_z if cycle == 0 else
                            (None if chain is None else chain[1]))
            if cycle and snapped is not None and snapped[0] < chain[0]:
                chain = snapped
        run += 1


def _carried(cov, coarse, fine, floor=0.1):
    """A run's covariance ``cov`` (its grid's unit coordinates) on the next,
    finer grid: ``J cov J^T`` with ``J`` the linear map between the grids'
    unit coordinates (coarse to the space, the space's least-squares image
    on the finer grid), scaled to a longest axis of 1, plus ``floor^2`` times
    the identity (the directions the coarse grid could not move in get a
    tenth of the longest axis)."""
    (_, Ec, _, wc, fc), (_, Ef, _, wf, ff) = coarse, fine
    J = Ec[:, fc] * wc                       # coarse unit -> the space's coordinates
    if Ef is not None:
        J = np.linalg.pinv(Ef) @ J
    J = J[ff] / wf[:, None]
    S = J @ cov @ J.T
    top = float(np.linalg.eigvalsh(S)[-1])
    if not (math.isfinite(top) and top > 0):
        return None
    return S / top + floor ** 2 * np.eye(len(S))


def _cma_run(ev, full, mean, sigma, lam, rng, until=math.inf, handoff=False,
             stuck=False, C0=None):
    """One run of CMA-ES from ``mean`` with step ``sigma`` (unit box), until
    the budget, ``until`` runs of the search, a counterexample, convergence
    (sigma below 1e-6 of the box), a stall (no better margin in 10 + 30 n /
    lambda generations; with ``stuck``, in 10 + 3 n / lambda), with
    ``handoff`` a gain of less than 1 % of the run's own in the last 10 + 3 n
    / lambda generations, or a margin flat over three populations in a row.
    Candidates are clipped into the box for their runs (a worst case on a
    face is reached exactly); the update reads them unclipped, as drawn, so
    the mean can move past a face the margin favours, where most samples land
    on it, but at most one standard deviation of the distribution past it in
    each coordinate (a sixth of the samples still fall inside there, so a
    coordinate whose optimum is inside keeps its ranking). Returns the last step,
    sigma times the longest axis of the distribution, and the covariance
    sigma^2 C. ``C0``: the first covariance (its longest axis 1; default the
    identity)."""
    n = mean.size
    mu = lam // 2
    w = math.log(mu + 0.5) - np.log(np.arange(1, mu + 1))
    w /= w.sum()
    mueff = 1.0 / np.sum(w ** 2)
    cc = (4 + mueff / n) / (n + 4 + 2 * mueff / n)
    cs = (mueff + 2) / (n + mueff + 5)
    c1 = 2 / ((n + 1.3) ** 2 + mueff)
    cmu = min(1 - c1, 2 * (mueff - 2 + 1 / mueff) / ((n + 2) ** 2 + mueff))
    damps = 1 + 2 * max(0.0, math.sqrt((mueff - 1) / (n + 1)) - 1) + cs
    chin = math.sqrt(n) * (1 - 1 / (4 * n) + 1 / (21 * n * n))
    pc, ps = np.zeros(n), np.zeros(n)
    B, D, C = np.eye(n), np.ones(n), np.eye(n)
    if C0 is not None:
        C = (C0 + C0.T) / 2
        ev2, B = np.linalg.eigh(C)
        D = np.sqrt(np.maximum(ev2, 1e-20))
    best, since, flat, g = math.inf, 0, 0, 0
    top = None                               # (margin, point of the space) of the run's best
    patience = 10 + math.ceil(30 * n / lam)
    trace = []                               # the best margin after each generation
    window = 10 + math.ceil(3 * n / lam)
    step = sigma
    while not ev.done and ev.n < until:
        step = sigma * float(D.max())
        Xr = mean + sigma * (rng.standard_normal((lam, n)) * D) @ B.T
        X = np.clip(Xr, 0.0, 1.0)            # what runs; the update reads Xr
        f = ev(full(X))
        if ev.done:
            return step, sigma ** 2 * C, top
        if np.ptp(f) == 0:                   # no ranking: widen, then start afresh
            flat += 1
            if flat >= 3:
                return step, sigma ** 2 * C, top
            sigma = min(1.0, sigma * math.exp(0.2 + cs / damps))
            continue
        flat, g = 0, g + 1
        if f.min() < best:
            best, since = float(f.min()), 0
            i = int(np.argmin(f))
            top = (best, full(X[i:i + 1])[0])
        else:
            since += 1
        trace.append(best)
        if (handoff and g > window
                and trace[-1 - window] - best <= 0.01 * (trace[0] - best)):
            return step, sigma ** 2 * C, top      # a coarse grid's own optimum, nearly
        sel = np.argsort(f, kind="stable")[:mu]
        Y = (Xr[sel] - mean) / sigma
        # the mean at most one of its distribution's standard deviations past
        # the box, coordinate by coordinate: a sixth of the samples still land
        # inside, so a coordinate whose bound is not its optimum still ranks
        sd = sigma * np.sqrt(np.maximum(np.diag(C), 0.0))
        yw = (np.clip(mean + sigma * (w @ Y), -sd, 1.0 + sd) - mean) / sigma
        mean = mean + sigma * yw
        ps = (1 - cs) * ps + math.sqrt(cs * (2 - cs) * mueff) * (B @ ((B.T @ yw) / D))
        hsig = (np.linalg.norm(ps) / math.sqrt(1 - (1 - cs) ** (2 * g)) / chin
                < 1.4 + 2 / (n + 1))
        pc = (1 - cc) * pc + hsig * math.sqrt(cc * (2 - cc) * mueff) * yw
        C = ((1 - c1 - cmu) * C + c1 * (np.outer(pc, pc) + (1 - hsig) * cc * (2 - cc) * C)
             + cmu * (Y.T * w) @ Y)
        sigma *= math.exp(cs / damps * (np.linalg.norm(ps) / chin - 1))
        sigma = min(sigma, 1.0)
        C = (C + C.T) / 2
        ev2, B = np.linalg.eigh(C)
        D = np.sqrt(np.maximum(ev2, 1e-20))
        if stuck and since > window:
            return step, sigma ** 2 * C, top      # no better than the point it started from
        if sigma * D.max() < 1e-6 or since > patience or D.max() > 1e7 * D.min():
            return step, sigma ** 2 * C, top
    return step, sigma ** 2 * C, top


def _snap(ev, space, z):
    """The point ``z`` of the space (a worst point) with its free coordinates
    at their nearer bound (the nearest vertex of the box), and with those
    within a tenth of their range of a bound there: two runs (a worst case
    held at its bounds, as bang-bang inputs are, that a search on a coarser
    grid approached). Returns (margin, point) of the better, or None."""
    if z is None:
        return None
    lo, hi = space.lo, space.hi
    free = hi > lo
    u = np.where(free, (z - lo) / np.where(free, hi - lo, 1.0), 0.0)
    vertex = np.where(free & (u >= 0.5), hi, lo)
    near = np.where(free & (u <= 0.1), lo, np.where(free & (u >= 0.9), hi, z))
    cand = np.unique(np.array([vertex, near]), axis=0)
    cand = cand[np.any(cand != z, axis=1)]
    if not len(cand):
        return None
    ev.stages.append((ev.n, "the worst point snapped to the box's bounds"))
    f = ev(cand)                             # +inf where not run
    i = int(np.argmin(f))
    return float(f[i]), cand[i]


def _seeded(ev, space, free, npop, rng, extremes=True):
    """The first population of a search over the free coordinates, (npop,
    n_free), its stages recorded on ``ev``: the entries' extreme members
    (with ``extremes``; a restart has run them already), vertices of the box,
    points on its faces and edges, a Latin hypercube."""
    lo, hi = space.lo[free], space.hi[free]
    nfree = int(free.sum())
    # a Latin hypercube, a quarter of it replaced by vertices of the box: worst
    # cases under bounded uncertainty are often extreme (bang-bang noise). The
    # vertices come first (the first population runs in chunks of 1, 2, 4, ...
    # when the search stops at a counterexample) and are distinct where the
    # box has few of them
    u = (rng.permuted(np.tile(np.arange(npop), (nfree, 1)), axis=1).T
         + rng.random((npop, nfree))) / npop
    nv = min(npop // 4, 2 ** min(nfree, 20))
    if nfree <= 12:
        corners = rng.choice(2 ** nfree, nv, replace=False)
        u[:nv] = (corners[:, None] >> np.arange(nfree)) & 1
    else:
        u[:nv] = rng.integers(0, 2, (nv, nfree))
    # before the vertices, the entries' extreme members that are not vertices
    # (a Sinusoids' constant ±bound signals lie on its face f = 0, with
    # sin φ = 1); after them, points on faces and edges of the box: each
    # coordinate at one of its bounds with probability 1/2, else its Latin
    # hypercube value (a worst case with some parameters at their bounds and
    # the others inside)
    ext = space.extremes(npop // 8, rng) if extremes else np.zeros((0, space.dim))
    ue = (ext[:, free] - lo) / (hi - lo)
    ne = len(ue)
    nf = max(0, min(npop // 8, npop - ne - nv)) if nfree > 1 else 0
    faces = u[nv:nv + nf].copy()
    at = rng.random(faces.shape) < 0.5
    faces[at] = rng.integers(0, 2, int(at.sum()))
    u = np.vstack([ue, u[:nv], faces, u[nv + nf:]])[:npop]
    init = lo + u * (hi - lo)
    n0 = ev.n
    for k, label in ((0, "a seeded extreme member of an entry (its extremes())"),
                     (ne, "a seeded vertex of the box"),
                     (ne + nv, "a seeded point on a face or an edge of the box"),
                     (ne + nv + nf, "the first population's Latin hypercube")):
        ev.stages.append((n0 + k, label))
    return init


def _refine(ev, space):
    """A compass (pattern) search from the worst point: each iteration tries a
    step of +h and -h along every free coordinate as one population, moves to
    the best if it improves, else halves h; steps are clipped into the box, so
    a worst case on a face or a vertex is reached exactly. While moves to a
    bound do best, each iteration also tries every free coordinate at each of
    its bounds (the edges from the point to the faces of the box). It stops
    when h falls below 1e-6, or when every step gave the point's own margin
    (a flat margin: the search's budget goes to fresh designs instead)."""
    free = np.flatnonzero(space.hi > space.lo)
    if not free.size:                        # every coordinate fixed: nothing to move
        return
    width = space.hi - space.lo
    z, best = ev.best_z.copy(), ev.best
    ev.stages.append((ev.n, "the compass search from the worst point"))
    h = 0.1
    snap = True                              # also each coordinate to each bound
    rows = np.arange(free.size)
    while not ev.done and h > 1e-6:
        cand = np.repeat(z[None, :], (4 if snap else 2) * free.size, axis=0)
        cand[rows, free] += h * width[free]
        cand[free.size + rows, free] -= h * width[free]
        if snap:
            cand[2 * free.size + rows, free] = space.lo[free]
            cand[3 * free.size + rows, free] = space.hi[free]
        cand = np.clip(cand, space.lo, space.hi)
        moved = np.any(cand != z, axis=1)    # a coordinate at its bound already: no run
        cand = cand[moved]
        is_snap = (np.arange(len(moved)) >= 2 * free.size)[moved]
        vals = ev(cand) if len(cand) else np.zeros(0)
        if len(vals) and np.all(vals == best):
            return                           # flat at every step: shorter ones tell no more
        k = int(np.argmin(vals)) if len(vals) else -1
        if k >= 0 and vals[k] < best:
            z, best = cand[k], vals[k]
            snap = snap and bool(is_snap[k])  # snapping stops once a step does better
        else:
            snap = False
            h /= 2



class _NoGradient(Exception):
    """The gradient is not defined at a point (or the refinement must stop)."""


def _refine_gradient(ev, space, sensitivity):
    """L-BFGS-B (scipy) from the worst point, on the free coordinates scaled
    to [0, 1], with the margin's gradient from the sensitivities: one run of
    ``sensitivity`` per evaluation, within what is left of the budget. Where
    the gradient is not defined, the compass search takes over."""
    from scipy.optimize import minimize

    from .sensitivity import SensitivityArc, SensitivityError, margin_gradient
    free = np.flatnonzero(space.hi > space.lo)
    if not free.size:
        return
    lo, width = space.lo[free], (space.hi - space.lo)[free]
    z0 = ev.best_z.copy()

    def full(u):
        z = z0.copy()
        z[free] = np.clip(lo + u * width, space.lo[free], space.hi[free])
        return z

    def fun(u):
        if ev.done:
            raise _NoGradient
        p = space.point(full(u))
        try:
            sarc = sensitivity(p)
        except SensitivityError as exc:     # the state's arc is fine, its gradient not
            if exc.arc is not None:
                ev._record(p, exc.arc.arc)
            raise _NoGradient from exc
        except Exception as exc:            # a failed run is a finding
            ev._record(p, exc)
            raise _NoGradient from exc
        if not isinstance(sarc, SensitivityArc) or sarc.system.m != space.dim:
            raise TypeError(f"run.sensitivity must return a SensitivityArc with one "
                            f"parameter per coordinate of the space ({space.dim}), got "
                            f"{sarc!r}")
        value = ev._record(p, sarc.arc)
        if value is None or not math.isfinite(value) or ev.found:
            raise _NoGradient
        try:
            g = margin_gradient(sarc, ev.claim)[free] * width
        except Exception as exc:            # the claim on the perturbed arcs
            raise _NoGradient from exc
        if not np.all(np.isfinite(g)):
            raise _NoGradient
        return value, g

    u0 = np.clip((z0[free] - lo) / width, 0.0, 1.0)
    ev.stages.append((ev.n, "gradient descent from the worst point"))
    try:
        minimize(fun, u0, jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * free.size,
                 options={"maxfun": max(1, ev.budget - ev.n), "ftol": 0.0, "gtol": 0.0})
    except _NoGradient:
        if not ev.done:
            _refine(ev, space)
