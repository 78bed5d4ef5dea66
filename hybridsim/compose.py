"""Interconnections: plants feeding observers, feedback loops (the builders of the
common shapes, :func:`connect` and :func:`network`, are in :mod:`hybridsim._compose_network`)."""
from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ._compose_checks import (
    _ND,
    _at,
    _guard_rows,
    _in_component,
    _input_value,
    _output_value,
    _rows_set,
    _rows_value,
    _state_value,
)
from .history import ComponentHistory
from .rules import MapError
from .system import HybridSystem, guard_min

__all__ = ["Interconnection", "LinearInput", "LinearPlant"]


def _matrix(name, M, shape=None):
    M = np.atleast_2d(np.asarray(M, dtype=float))
    if M.ndim != 2:
        raise ValueError(f"{name} must be a 2-D matrix, got {M.ndim} dimensions")
    if shape is not None:
        exp = tuple(s if s is not None else M.shape[k] for k, s in enumerate(shape))
        if M.shape != exp:
            raise ValueError(f"{name} must have shape {exp}, got {M.shape}")
    if not np.all(np.isfinite(M)):
        raise ValueError(f"{name} must be finite")
    return M


class LinearPlant(HybridSystem):
    r"""A linear plant :math:`\dot x = Ax + Bu + d(t)`, :math:`y = Cx + Du + m(t)`.

    Parameters
    ----------
    A : array_like (n, n), or an object with attributes ``A, B, C, D``
        State matrix, or a state-space object (e.g. python-control's
        ``StateSpace``; python-control is not imported).
    B : array_like (n, m), optional
    C : array_like (p, n), optional
        Output matrix (default: the identity, y = x).
    D : array_like (p, m), optional
        Feedthrough (default 0). Must be 0 when u comes from an
        interconnection (outputs may not depend on inputs).
    u : callable, optional
        Exogenous input ``u(t) -> (m,)``. When B is given and u is None, the
        plant has ``input_dim = m`` and takes u from an interconnection.
    noise : callable, optional
        Measurement noise ``m(t) -> (p,)`` added to the output.
    disturbance : callable, optional
        Process disturbance ``d(t) -> (n,)`` added to the flow.

    Notes
    -----
    Without ``u``, ``noise`` and ``disturbance`` callables the plant is
    ``vectorized``: its maps also take batches x of shape (N, n) (and u of
    shape (N, m)), so an interconnection of vectorized components runs
    through the batch integrator of :func:`hybridsim.simulate_many`. Put a
    batch's noise in a component's state (e.g. a noise generator) rather
    than in a callable of t.
    """

    def __init__(self, A, B=None, C=None, D=None, *, u=None, noise=None, disturbance=None):
        if all(hasattr(A, k) for k in ("A", "B", "C", "D")):
            ss = A
            A, B, C, D = ss.A, ss.B if B is None else B, ss.C if C is None else C, \
                ss.D if D is None else D
        A = _matrix("A", A)
        n = A.shape[0]
        if A.shape != (n, n):
            raise ValueError(f"A must be square, got shape {A.shape}")
        self.A = A
        self.B = None if B is None else _matrix(
            "B", np.reshape(B, (n, -1)) if np.ndim(B) == 1 else B, (n, None))
        m = 0 if self.B is None else self.B.shape[1]
        self.C = np.eye(n) if C is None else _matrix("C", C, (None, n))
        p = self.C.shape[0]
        self.D = np.zeros((p, m)) if D is None else _matrix("D", D, (p, m))
        for name, fn in (("u", u), ("noise", noise), ("disturbance", disturbance)):
            if fn is not None and not callable(fn):
                raise TypeError(f"{name} must be a callable of t, got {type(fn).__name__}")
        if u is not None and self.B is None:
            raise ValueError("u is given but B is None: pass B (n, m) with the input")
        self.u = u
        self.noise = noise
        self.disturbance = disturbance
        self.state_dim = n
        self.output_dim = p
        self.input_dim = m if (self.B is not None and u is None) else 0
        if self.input_dim and np.any(self.D != 0):
            raise ValueError("D must be zero when the plant's input comes from an "
                             "interconnection (outputs may not depend on inputs); pass u=callable "
                             "for an exogenous input")
        self._check_signal("u", u, m)
        self._check_signal("noise", noise, p)
        self._check_signal("disturbance", disturbance, n)

    @staticmethod
    def _check_signal(name, fn, dim):
        if fn is None:
            return
        v = np.atleast_1d(np.asarray(fn(0.0), dtype=float))
        if v.shape != (dim,):
            raise ValueError(f"{name}(t) must return shape ({dim},), got {v.shape}")

    @property
    def vectorized(self):
        """True when the plant has no callables of t (see Notes)."""
        return self.u is None and self.noise is None and self.disturbance is None

    # one form on the last axis: x (n,) or a batch (N, n) (u (m,) or (N, m)); the
    # callables of t make the plant single-state (not vectorized)
    def flow_map(self, x, t, j, u):
        dx = x @ self.A.T
        if self.B is not None:
            uu = self.u(t) if self.u is not None else u
            dx += np.atleast_1d(np.asarray(uu, dtype=float)) @ self.B.T
        if self.disturbance is not None:
            dx = dx + self.disturbance(t)
        return dx

    def output(self, x, t, j):
        y = x @ self.C.T
        if self.u is not None and self.B is not None:
            y = y + np.atleast_1d(np.asarray(self.u(t), dtype=float)) @ self.D.T
        if self.noise is not None:
            y = y + self.noise(t)
        return y


class _Outputs(Mapping):
    """Lazy ``{name: output}`` of an interconnection at one (x, t, j)."""

    __slots__ = ("_ic", "_x", "_t", "_j", "_cache", "_busy")

    def __init__(self, ic, x, t, j):
        self._ic, self._x, self._t, self._j = ic, x, t, j
        self._cache = {}
        self._busy = None

    def __getitem__(self, name):
        c = self._cache
        if name in c:
            return c[name]
        ic = self._ic
        try:
            sl = ic._slices[name]
        except KeyError:
            raise KeyError(f"no component named {name!r}; have {list(ic._slices)}") from None
        u = None
        if ic._h_u[name]:           # direct feedthrough: the input first
            busy = self._busy if self._busy is not None else set()
            if name in busy:
                raise ValueError(f"algebraic loop: the output of {name!r} depends on its own "
                                 f"input through {sorted(map(str, busy))}")
            busy.add(name)
            self._busy = busy
            try:
                u = ic._u(name, self._x, self._t, self._j, self)
            finally:
                busy.discard(name)
        y = ic._h[name](self._x[..., sl], self._t, self._j, u)
        spec = ic._hout.get(name)   # an overridden output is checked (else y is the state)
        if spec is not None and not (y.__class__ is _ND and y.shape == spec
                                     and y.dtype.kind == "f"):
            x = self._x
            y = _output_value(name, y, ic._hp[name], len(x) if x.ndim == 2 else None,
                              self._t, self._j)
        c[name] = y
        return y

    def __iter__(self):
        return iter(self._ic._slices)

    def __len__(self):
        return len(self._ic._slices)


class LinearInput:
    r"""An input wired linearly from outputs: :math:`u = \sum_s M_s\, y_s`.

    The wiring every integration path understands, the compiled one included
    (an arbitrary callable ``(t, y) -> u`` runs on the Python and vectorized
    paths only). :func:`connect` wires with it; pass it in
    :class:`Interconnection`'s ``inputs`` or :func:`network`'s.

    Parameters
    ----------
    terms : dict
        ``{source: M}``: ``source`` names a component, ``M`` is its
        (input_dim, output_dim) matrix, or ``None`` for the identity
        (u = y_source; then there is a single term).

    Examples
    --------
    >>> import numpy as np, hybridsim as hs
    >>> w = hs.LinearInput({"plant": None, "noise": None})      # u = y_plant + y_noise
    >>> w(0.0, {"plant": np.array([1.0, 2.0]), "noise": np.array([0.5, 0.5])})
    array([1.5, 2.5])
    >>> w = hs.LinearInput({"a": [[1.0, 0.0], [0.0, 0.0]], "b": [[0.0], [1.0]]})
    >>> w(0.0, {"a": np.array([3.0, 4.0]), "b": np.array([5.0])})   # u = (a_1, b)
    array([3., 5.])
    """

    __slots__ = ("terms", "_take")

    def __init__(self, terms):
        if not isinstance(terms, Mapping) or not terms:
            raise TypeError(f"terms must be a non-empty dict {{source: matrix or None}}, "
                            f"got {type(terms).__name__}")
        out = {}
        for src, M in terms.items():
            out[src] = None if M is None else _matrix(f"terms[{src!r}]", M)
        rows = {M.shape[0] for M in out.values() if M is not None}
        if len(rows) > 1:
            raise ValueError(f"terms: every matrix must have the same number of rows "
                             f"(the input's dimension), got {sorted(rows)}")
        self.terms = out
        self._take = _selection(out)

    def __call__(self, t, y):
        take = self._take
        if take is not None:
            idx, width = take
            v = np.concatenate([y[src] for src in self.terms], axis=-1)
            if v.shape[-1] == width and v.dtype.kind == "f":
                u = v.take(idx, axis=-1)
                u += 0.0            # M @ v gives +0.0 where the selected value is -0.0
                return u
        u = None
        for src, M in self.terms.items():
            v = y[src]
            if M is not None:
                v = v @ M.T if np.ndim(v) == 2 else M @ v
            u = v if u is None else u + v
        return u

    def input_dim(self, output_dims):
        """The input's dimension given ``{source: output_dim}`` (checking the shapes)."""
        m = None
        for src, M in self.terms.items():
            q = output_dims[src]
            if M is None:
                k = q
            else:
                if M.shape[1] != q:
                    raise ValueError(f"LinearInput: terms[{src!r}] has {M.shape[1]} columns "
                                     f"but {src!r} has {q} outputs")
                k = M.shape[0]
            if m is not None and k != m:
                raise ValueError(f"LinearInput: the terms give inputs of dimensions {m} and "
                                 f"{k}; they must agree")
            m = k
        return m

    def __repr__(self):
        return f"LinearInput({{{', '.join(map(repr, self.terms))}}})"

    def __getstate__(self):
        return self.terms

    def __setstate__(self, s):
        self.terms = s
        self._take = _selection(s)


def _selection(terms):
    """Where every term's matrix selects (each row one 1, else 0; the terms' rows
    disjoint and covering the input): ``(idx, width)`` with ``u = concat(y_s)[idx]``,
    the same numbers as the sum of the products; else None."""
    if any(M is None for M in terms.values()):
        return None
    m = next(iter(terms.values())).shape[0]
    idx = np.full(m, -1, dtype=np.intp)
    off = 0
    for M in terms.values():
        if not np.all((M == 0.0) | (M == 1.0)):
            return None
        ones = M == 1.0
        rows = np.flatnonzero(ones.any(axis=1))
        if (ones.sum(axis=1) > 1).any() or (idx[rows] >= 0).any():
            return None
        idx[rows] = off + np.argmax(ones[rows], axis=1)
        off += M.shape[1]
    return None if (idx < 0).any() else (idx, off)


class Interconnection(HybridSystem):
    """Several hybrid systems with one state vector, wired output to input.

    Parameters
    ----------
    systems : dict
        ``{name: HybridSystem}``, in the order their states are stacked.
    inputs : dict, optional
        ``{name: callable(t, y) -> u}`` for each component with an input,
        where ``y`` maps every component's name to its output at the current
        (x, t, j). Exogenous signals are plain functions of t inside it.
    name : str, optional

    Notes
    -----
    * The components flow together: the flow map stacks theirs.
    * x is in C when every component is in its flow set; x is in D when some
      component is in its jump set.
    * At a jump of the interconnection, every component in its jump set
      jumps at once (simultaneously, each from the pre-jump values); the
      others keep their state. The interconnection's j counts all jumps,
      and each component's maps receive that j.
    * ``arc.component(name)`` (or ``arc[name]``) gives a component's part.
    * Each component's values are checked: its flow and jump maps must return
      finite reals of shape (n_i,) (over a batch (N, n_i)), an output with a
      declared ``output_dim`` p shape (p,) ((N, p)), a batch guard (N,) or
      (N, m), a batch set (N,). Otherwise a :class:`hybridsim.MapError` names
      the component and the map (``map_name="plant.flow_map"``), t and j.
    * There is no cap on the number of components.
    * When every component is ``vectorized`` (reading its past or not),
      so is the interconnection: :func:`hybridsim.simulate_many` then
      integrates a batch of it together, each component's maps receiving
      batches (its slice of the rows' states, the rows' t and j, and its
      input computed over the rows), and at a jump each component jumps on
      the rows where it is in its jump set. The input callables then
      receive batched outputs ``y[name]`` of shape (N, p).
    """

    def __init__(self, systems, inputs=None, *, name=None):
        if not isinstance(systems, Mapping) or not systems:
            raise TypeError("systems must be a non-empty dict {name: HybridSystem}")
        inputs = {} if inputs is None else dict(inputs)
        self.systems = dict(systems)
        self._slices = {}
        k = 0
        for nm, s in self.systems.items():
            if not isinstance(s, HybridSystem):
                raise TypeError(f"systems[{nm!r}] must be a HybridSystem, got {type(s).__name__}")
            drawn = [k for k in ("diffusion", "jump_rate", "jump_law")
                     if getattr(s, k, None) is not None]
            if drawn:
                raise ValueError(f"systems[{nm!r}] declares {', '.join(drawn)}: an "
                                 f"interconnection does not carry SDE flows or random jumps "
                                 f"yet (its noise would be dropped); simulate the component "
                                 f"alone, or write the closed loop as one system")
            s._compile()
            self._slices[nm] = slice(k, k + int(s.state_dim))
            k += int(s.state_dim)
        for nm in inputs:
            if nm not in self.systems:
                raise ValueError(f"inputs: {nm!r} is not a component; have {list(self.systems)}")
            if not callable(inputs[nm]):
                raise TypeError(f"inputs[{nm!r}] must be a callable (t, y) -> u")
            if isinstance(inputs[nm], LinearInput):
                bad = [s for s in inputs[nm].terms if s not in self.systems]
                if bad:
                    raise ValueError(f"inputs[{nm!r}]: the LinearInput reads {bad}, which "
                                     f"are not components; have {list(self.systems)}")
        for nm, s in self.systems.items():
            if int(s.input_dim or 0) > 0 and nm not in inputs:
                raise ValueError(f"inputs: component {nm!r} has input_dim={s.input_dim} "
                                 "but no entry in inputs")
        self.inputs = inputs
        self.components = dict(self._slices)
        self.state_dim = k
        self.input_dim = 0
        self._name = name
        hints = [s.max_step for s in self.systems.values() if s.max_step is not None]
        self.max_step = min(hints) if hints else None
        self.needs_history = any(s.needs_history for s in self.systems.values())
        # a batch of the whole interconnection when every component takes batches
        # (the past too: each component reads its rows' through a ComponentHistory)
        self.vectorized = all(bool(s.vectorized) for s in self.systems.values())
        self.delays = tuple(sorted({float(d) for s in self.systems.values()
                                    for d in (s.delays or ())}))
        self._build()

    _DERIVED = ("_f", "_g", "_C", "_D", "_Cv", "_Dv", "_h", "_h_u", "_hD", "_hC", "_items", "_m",
                "_reads_u", "_jump_set_of_guard",
                "_hout", "_hp", "jump_guard",
                "flow_guard", "_compiled_maps", "history", "_lowered")

    def _build(self):
        """Tables of the components' compiled maps (rebuilt after unpickling)."""
        c = {nm: s._compile() for nm, s in self.systems.items()}
        self._f = {nm: c[nm].f for nm in c}
        self._g = {nm: c[nm].g for nm in c}
        self._C = {nm: c[nm].C for nm in c if c[nm].has_C}
        self._D = {nm: c[nm].D for nm in c if c[nm].has_D}
        self._h = {nm: c[nm].h for nm in c}
        self._h_u = {nm: c[nm].h_u for nm in c}
        self._hD = {nm: c[nm].hD for nm in self._D}
        self._hC = {nm: c[nm].hC for nm in self._C}
        # {table: the components whose test reads its input}: the others get u = None,
        # so their input is not computed for a set or guard (hybridsim.system.reads_input)
        self._reads_u = {key: {nm for nm in tab if getattr(c[nm], key)}
                         for tab, key in ((self._C, "C_u"), (self._D, "D_u"),
                                          (self._hD, "hD_u"), (self._hC, "hC_u"))}
        # composite guards only where every relevant component has one
        if self._D and all(h is not None for h in self._hD.values()):
            self.jump_guard = self._jump_guard
            # any(min h_i >= 0) is max_i min h_i >= 0: jump_set is {jump_guard >= 0}
            self._jump_set_of_guard = all(c[nm].D_guard for nm in self._D)
        if self._C and all(h is not None for h in self._hC.values()):
            self.flow_guard = self._flow_guard
        self._m = {nm: int(s.input_dim or 0) for nm, s in self.systems.items()}
        # (name, slice, flow map, input, (n_i,)): the flow's loop
        self._items = [(nm, self._slices[nm], self._f[nm], self.inputs.get(nm),
                        (self._slices[nm].stop - self._slices[nm].start,))
                       for nm in self.systems]
        # overridden outputs are checked: {name: output_dim or None} and the shape
        # of a single state's output ((p,), or (-1,), matching none, where undeclared)
        self._hp = {nm: (None if s.output_dim is None else int(s.output_dim))
                    for nm, s in self.systems.items() if s._overrides("output")}
        self._hout = {nm: (-1 if p is None else p,) for nm, p in self._hp.items()}
        # the batch path's sets: the components' own indicators (arrays), or
        # {min_i h_i >= 0} of their guards
        self._Cv = {nm: _rows_set(nm, s, "flow") for nm, s in self.systems.items()
                    if nm in self._C}
        self._Dv = {nm: _rows_set(nm, s, "jump") for nm, s in self.systems.items()
                    if nm in self._D}

    def __getstate__(self):
        state = self.__dict__.copy()
        for k in self._DERIVED:
            state.pop(k, None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self._build()

    # -- wiring --------------------------------------------------------------
    def _u(self, name, x, t, j, y=None):
        fn = self.inputs.get(name)
        if fn is None:
            return None
        return self._input(name, fn, x, t, j, _Outputs(self, x, t, j) if y is None else y)

    def _input(self, nm, fn, x, t, j, y):
        """Component ``nm``'s input ``fn(t, y)``, checked against its input_dim
        (:func:`_input_value`); its failure a MapError naming ``inputs[nm]``."""
        try:
            u = fn(t, y)
        except MapError:
            raise
        except Exception as e:
            tt, jj = _at(t, j)
            where = "" if tt is None else f" (at t={tt:.10g}, j={jj})"
            raise MapError(f"inputs[{nm!r}] raised {type(e).__name__}: {e}{where}",
                           f"inputs[{nm!r}]", tt, jj) from e
        m = self._m[nm]
        if m:
            k = len(x) if x.ndim == 2 else None
            if not (u.__class__ is _ND and u.dtype.kind == "f"
                    and u.shape == ((m,) if k is None else (k, m))
                    and math.isfinite(u.dot(u) if k is None else u.sum())):
                _input_value(nm, u, m, k, t, j)     # (or an overflow of the product)
        return u

    def _input_of(self, name, x, t, j):
        return self._u(name, x, t, j)

    def output(self, x, t, j):
        return x

    def outputs(self, x, t=0.0, j=0):
        """``{name: output}`` of every component at (x, t, j)."""
        y = _Outputs(self, np.asarray(x, dtype=float), t, j)
        return {nm: y[nm] for nm in self.systems}

    # -- data ------------------------------------------------------------------
    # A single state x (n,) takes the scalar path; a batch x (N, n), t and j
    # (N,) (a vectorized interconnection inside simulate_many) the array path:
    # each component's maps see their slice x[:, sl] and the rows' own t, j, u.
    #
    # Every component's value is checked before it goes in its slice: real,
    # finite, of shape (n_i,) (a batch: (N, n_i)); else a MapError names the
    # component ("plant.flow_map"), t and j. The fast path is a few attribute
    # tests and a dot product (a sum over a batch) per component.
    #
    # Why two forms here (the batch branches, _jump_rows, _rows_set with
    # _guard_rows/_set_rows): a single state reads each component's engine
    # maps (its sets derived from its guards, the single-state checks), which
    # every component has, vectorized or not; a batch reads the components'
    # own batch maps with checks naming the row, and jumps each component on
    # its rows only (masks; t, j and u per row), where a single state jumps
    # the components in D one by one, computing only their inputs. The
    # compiled path runs none of this: it generates the stacked maps from
    # the parts' Components (hybridsim.compiled._lower).
    def flow_map(self, x, t, j, u=None):
        y = _Outputs(self, x, t, j)
        out = np.empty(x.shape)
        nm = None
        try:
            if x.ndim == 2:
                k = len(x)
                for nm, sl, f, ufn, (n,) in self._items:
                    v = f(x[:, sl], t, j, None if ufn is None else self._input(nm, ufn, x, t, j, y))
                    if not (v.__class__ is _ND and v.shape == (k, n) and v.dtype.kind == "f"):
                        v = _rows_value(nm, "flow_map", v, k, n, t, j)
                    out[:, sl] = v
                if not math.isfinite(out.sum()):        # (or an overflow of the sum)
                    self._non_finite("flow_map", out, t, j)
                return out
            for nm, sl, f, ufn, shape in self._items:
                v = f(x[sl], t, j, None if ufn is None else self._input(nm, ufn, x, t, j, y))
                if not (v.__class__ is _ND and v.shape == shape and v.dtype.kind == "f"):
                    v = _state_value(nm, "flow_map", v, shape[0], t, j)
                out[sl] = v
        except MapError as e:
            if nm is None:
                raise
            raise _in_component(nm, e) from e.__cause__
        if not math.isfinite(out.dot(out)):         # (or an overflow of the product)
            self._non_finite("flow_map", out, t, j)
        return out

    def _non_finite(self, kind, out, t, j):
        """Raise the MapError naming the first component whose part of ``out`` is not
        finite (none where the fast test only overflowed)."""
        for nm, sl in self._slices.items():
            v = out[..., sl]
            if not np.isfinite(v).all():
                if v.ndim == 2:
                    _rows_value(nm, kind, v, len(v), sl.stop - sl.start, t, j)
                _state_value(nm, kind, v, sl.stop - sl.start, t, j)

    def _in(self, table, x, t, j, y, reads=None):
        """(name, test's value) for each component of ``table``; ``reads``: the names
        whose test is given its input (None: every one); ``y``: the outputs at (x, t, j),
        or None (made when an input is first needed)."""
        for nm, test in table.items():
            try:
                if reads is None or nm in reads:
                    if y is None:
                        y = _Outputs(self, x, t, j)
                    u = self._u(nm, x, t, j, y)
                else:
                    u = None
                v = test(x[..., self._slices[nm]], t, j, u)
            except MapError as e:
                raise _in_component(nm, e) from e.__cause__
            yield nm, v

    # The batch branches below are kept on purpose: one state stops at the first
    # component outside C (or inside D) and computes an input only for the tests
    # that read it, where a batch must test every component on every row; a batch
    # jump applies each component's g to its own rows of D only (g need not be
    # defined off D), which a last-axis form evaluating g on every row cannot do.
    def flow_set(self, x, t, j, u=None):
        if np.ndim(x) == 2:
            ok = np.ones(len(x), dtype=bool)
            for _, v in self._in(self._Cv, x, t, j, None):
                ok &= v
            return ok
        return all(v for _, v in self._in(self._C, x, t, j, None, self._reads_u["C_u"]))

    def jump_set(self, x, t, j, u=None):
        if np.ndim(x) == 2:
            inD = np.zeros(len(x), dtype=bool)
            for _, v in self._in(self._Dv, x, t, j, None):
                inD |= v
            return inD
        return any(v for _, v in self._in(self._D, x, t, j, None, self._reads_u["D_u"]))

    def jump_map(self, x, t, j, u=None):
        y = _Outputs(self, x, t, j)
        xn = np.array(x, dtype=float)
        if np.ndim(x) == 2:
            return self._jump_rows(x, t, j, y, xn)
        for nm, inD in list(self._in(self._D, x, t, j, y, self._reads_u["D_u"])):
            if inD:
                sl = self._slices[nm]
                try:
                    v = self._g[nm](x[sl], t, j, self._u(nm, x, t, j, y))
                except MapError as e:
                    raise _in_component(nm, e) from e.__cause__
                n = sl.stop - sl.start
                if not (v.__class__ is _ND and v.shape == (n,) and v.dtype.kind == "f"
                        and math.isfinite(v.dot(v))):
                    v = _state_value(nm, "jump_map", v, n, t, j)
                xn[sl] = v
        return xn

    def _jump_rows(self, x, t, j, y, xn):
        """Batch jump: each component jumps on the rows where it is in its D."""
        t, j = np.asarray(t), np.asarray(j)
        for nm, inD in list(self._in(self._Dv, x, t, j, y)):
            rows = np.asarray(inD, dtype=bool)
            if not rows.any():
                continue
            sl = self._slices[nm]
            u = self._u(nm, x, t, j, y)
            if u is not None:
                u = np.asarray(u, dtype=float)[rows]
            tr, jr = t[rows], j[rows]
            try:
                v = self._g[nm](x[rows][:, sl], tr, jr, u)
            except MapError as e:
                raise _in_component(nm, e) from e.__cause__
            k, n = len(tr), sl.stop - sl.start
            if not (v.__class__ is _ND and v.shape == (k, n) and v.dtype.kind == "f"
                    and math.isfinite(v.sum())):
                v = _rows_value(nm, "jump_map", v, k, n, tr, jr)
            xn[rows, sl] = v
        return xn

    def _jump_guard(self, x, t, j, u=None):
        vals = self._in(self._hD, x, t, j, None, self._reads_u["hD_u"])
        if np.ndim(x) == 2:
            return np.max([_guard_rows(nm, "jump_guard", h, len(x), t, j) for nm, h in vals],
                          axis=0)
        return max(guard_min(h) for _, h in vals)

    def _flow_guard(self, x, t, j, u=None):
        vals = self._in(self._hC, x, t, j, None, self._reads_u["hC_u"])
        if np.ndim(x) == 2:
            return np.min([_guard_rows(nm, "flow_guard", h, len(x), t, j) for nm, h in vals],
                          axis=0)
        return min(guard_min(h) for _, h in vals)

    @property
    def has_jumps(self):
        return bool(self._D)

    @property
    def has_flow_boundary(self):
        return bool(self._C)

    def _bind_history(self, history):
        self.history = history
        for nm, s in self.systems.items():
            s._bind_history(ComponentHistory(history, self._slices[nm], self, nm))

    def split(self, x):
        """The parts of a stacked state, keyed by component name.

        Parameters
        ----------
        x : array_like, shape (n,) or (N, n)
            A stacked state, or N of them (e.g. ``arc.x``).

        Returns
        -------
        dict
            ``{name: part}`` in stacking order, each part of shape (n_i,) or
            (N, n_i); the names are the components' own (any hashable: the
            node names of :func:`network`).

        Raises
        ------
        ValueError
            The last axis of x is not the interconnection's ``state_dim``.

        Examples
        --------
        >>> import hybridsim as hs
        >>> ic = hs.Interconnection({0: hs.LinearPlant([[0.0]]), (1, "b"): hs.LinearPlant([[0.0]])})
        >>> ic.split([1.0, 2.0])
        {0: array([1.]), (1, 'b'): array([2.])}
        """
        x = np.asarray(x)
        if x.ndim == 0 or x.shape[-1] != self.state_dim:
            raise ValueError(f"split: x must have shape ({self.state_dim},) or (N, "
                             f"{self.state_dim}) (the stacked state of {list(self._slices)}), "
                             f"got {x.shape}")
        return {nm: x[..., sl] for nm, sl in self._slices.items()}

    def stack(self, parts=None, /, **named):
        """The stacked state from one part per component.

        Parameters
        ----------
        parts : mapping, optional
            ``{name: part}``: any hashable names (ints, tuples: the node
            names of :func:`network`).
        **named
            ``name=part`` for components named by strings (may be combined
            with ``parts``; a name given twice is an error).

        Returns
        -------
        numpy.ndarray, shape (n,)
            The parts in stacking order (the inverse of :meth:`split`).

        Raises
        ------
        ValueError
            A component is missing, a name is not a component, or a part
            has the wrong shape.
        TypeError
            ``parts`` is not a mapping.

        Examples
        --------
        >>> import hybridsim as hs
        >>> ic = hs.Interconnection({0: hs.LinearPlant([[0.0]]), 1: hs.LinearPlant([[0.0]])})
        >>> ic.stack({1: 2.0, 0: 1.0})
        array([1., 2.])
        """
        if parts is None:
            parts = {}
        elif not isinstance(parts, Mapping):
            raise TypeError(f"stack: parts must be a mapping {{name: part}} (or use name=part "
                            f"keywords), got {type(parts).__name__}")
        both = [nm for nm in named if nm in parts]
        if both:
            raise ValueError(f"stack: parts for {both} given twice (in the mapping and as "
                             "keywords)")
        parts = {**parts, **named}
        missing = [nm for nm in self.systems if nm not in parts]
        if missing:
            raise ValueError(f"stack: missing parts for components {missing}")
        extra = [nm for nm in parts if nm not in self.systems]
        if extra:
            raise ValueError(f"stack: {extra} are not components; have {list(self.systems)}")
        out = np.empty(self.state_dim)
        for nm, sl in self._slices.items():
            v = np.atleast_1d(np.asarray(parts[nm], dtype=float))
            if v.shape != (sl.stop - sl.start,):
                raise ValueError(f"stack: part {nm!r} must have shape ({sl.stop - sl.start},), "
                                 f"got {v.shape}")
            out[sl] = v
        return out
