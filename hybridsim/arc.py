"""Hybrid arcs: solutions on hybrid time domains."""
from __future__ import annotations

import bisect
import numpy as np

from .rules import Termination  # one source of the causes

__all__ = ["HybridArc", "Termination"]


class HybridArc:
    """A solution of a hybrid system on its hybrid time domain.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Ordinary time of each sample (non-decreasing).
    j : ndarray of int, shape (N,)
        Jump counter of each sample. A jump appears as two consecutive samples
        with the same t and j, j + 1.
    x : ndarray, shape (N, n)
        The state at each sample (time-major).
    termination : Termination
        Why the run stopped; ``termination.message`` explains it.
    message : str
        A sentence saying why the run stopped (with details where known).
    exception : BaseException or None
        The exception a user map raised (``termination is MAP_ERROR``).
    components : dict or None
        ``{name: slice}`` of an interconnection's parts (see :meth:`component`).
    """

    def __init__(self, t, j, x, termination, message=None, exception=None,
                 components=None, segments=None, system=None):
        self.t = np.asarray(t, dtype=float)
        self.j = np.asarray(j, dtype=np.int64)
        self.x = np.asarray(x, dtype=float)
        if self.x.ndim != 2 or len(self.x) != len(self.t) or len(self.j) != len(self.t):
            raise ValueError(f"HybridArc: expected t (N,), j (N,), x (N, n); got shapes "
                             f"{self.t.shape}, {self.j.shape}, {self.x.shape}")
        self.termination = termination
        self.message = message or (termination.message if termination else "")
        self.exception = exception
        self.components = components
        self.system = system
        self._segments = segments  # list of (t_a, t_b, j, dense) or None

    # ------------------------------------------------------------------ basics
    def __len__(self):
        return len(self.t)

    def __repr__(self):
        return (f"<HybridArc: {len(self.t)} samples, t in [{self.t[0]:.6g}, "
                f"{self.t[-1]:.6g}], {self.jump_count} jumps, "
                f"termination={self.termination.name if self.termination else None}>")

    @property
    def termination_cause(self):
        """Alias of :attr:`termination` (HyEQ toolbox name)."""
        return self.termination

    @property
    def success(self) -> bool:
        """True when the run stopped at t_max or j_max."""
        return bool(self.termination is not None and self.termination.success)

    @property
    def state_dim(self) -> int:
        return self.x.shape[1]

    @property
    def x0(self):
        return self.x[0]

    @property
    def xf(self):
        return self.x[-1]

    @property
    def t0(self) -> float:
        return float(self.t[0])

    @property
    def tf(self) -> float:
        return float(self.t[-1])

    @property
    def jf(self) -> int:
        return int(self.j[-1])

    @property
    def jump_index(self):
        """Indices k of the post-jump samples (``j[k] == j[k-1] + 1``)."""
        return np.flatnonzero(np.diff(self.j) > 0) + 1

    @property
    def jump_times(self):
        """Times t at which the jumps happened, shape (jump_count,)."""
        return self.t[self.jump_index]

    @property
    def jump_count(self) -> int:
        return int(self.j[-1] - self.j[0])

    @property
    def flow_intervals(self):
        """List of ``(t_start, t_end, j)``: the interval [t_j, t_{j+1}] of each j."""
        out = []
        starts = np.concatenate(([0], self.jump_index))
        ends = np.concatenate((self.jump_index - 1, [len(self.t) - 1]))
        for a, b in zip(starts, ends):
            out.append((float(self.t[a]), float(self.t[b]), int(self.j[a])))
        return out

    @property
    def flow_lengths(self):
        """Length t_{j+1} - t_j of each interval of flow, shape (jump_count + 1,)."""
        return np.array([b - a for a, b, _ in self.flow_intervals])

    # ------------------------------------------------------------ selection
    def _subset(self, mask):
        mask = np.asarray(mask, dtype=bool)
        return HybridArc(self.t[mask], self.j[mask], self.x[mask], self.termination,
                         self.message, self.exception, self.components,
                         self._segments, self.system)

    def select(self, t=None, j=None):
        """The samples with t in ``t`` and j in ``j``.

        Parameters
        ----------
        t : (float, float), optional
            Closed interval [a, b] of ordinary time.
        j : int or (int, int), optional
            One jump count, or a closed range of them.
        """
        mask = np.ones(len(self.t), dtype=bool)
        if t is not None:
            a, b = t
            mask &= (self.t >= a) & (self.t <= b)
        if j is not None:
            if np.ndim(j) == 0:
                mask &= self.j == j
            else:
                lo, hi = j
                mask &= (self.j >= lo) & (self.j <= hi)
        if not mask.any():
            raise ValueError(f"select: no sample with t in {t} and j in {j}")
        return self._subset(mask)

    def at(self, t, j=None):
        """The state at hybrid time (t, j), interpolated.

        With ``j=None`` the last sample at t is used (after any jumps at t).
        Interpolation uses the solver's dense output where the run kept it
        (``simulate(..., dense=True)``), else it is linear between samples.
        """
        t = float(t)
        if j is None:
            k = np.searchsorted(self.t, t, side="right") - 1
            if k < 0 or t > self.t[-1]:
                raise ValueError(f"at: t={t} is outside the arc's time range "
                                 f"[{self.t[0]}, {self.t[-1]}]")
            j = int(self.j[k])
        idx = np.flatnonzero(self.j == j)
        if idx.size == 0:
            raise ValueError(f"at: the arc has no sample with j={j}")
        ts = self.t[idx]
        if t < ts[0] or t > ts[-1]:
            raise ValueError(f"at: (t={t}, j={j}) is not in the hybrid time domain "
                             f"(for j={j}, t lies in [{ts[0]}, {ts[-1]}])")
        if self._segments:
            starts = self.__dict__.get("_seg_starts")
            if starts is None:
                starts = self.__dict__["_seg_starts"] = [sg[0] for sg in self._segments]
            k = bisect.bisect_right(starts, t) - 1
            # the segment of this j covering t (at a jump time, step back to it)
            while k >= 0 and self._segments[k][1] >= t:
                a, b, jj, sol = self._segments[k]
                if jj == j and a <= t <= b:
                    return np.asarray(sol(t), dtype=float)
                if jj < j:
                    break
                k -= 1
        k = np.searchsorted(ts, t, side="right") - 1
        k = min(k, len(ts) - 2) if len(ts) > 1 else 0
        if len(ts) == 1 or ts[k + 1] == ts[k]:
            return self.x[idx[k]].copy()
        w = (t - ts[k]) / (ts[k + 1] - ts[k])
        return (1 - w) * self.x[idx[k]] + w * self.x[idx[k + 1]]

    __call__ = at

    def evaluate(self, fn):
        """Evaluate ``fn(x, t, j)`` (or ``fn(x)``, ``fn(x, t)``) at every sample.

        Returns an array of shape (N, ...) stacking the results.
        """
        from .system import as_map
        f = as_map(fn, "fn")
        return np.array([np.asarray(f(x, t, j, None)) for x, t, j in
                         zip(self.x, self.t, self.j)])

    # ---------------------------------------------------------- components
    def component(self, name):
        """The part of an interconnection's state named ``name``, as an arc."""
        if not self.components:
            raise KeyError("component: this arc is not the solution of an "
                           "interconnection (it has no named components)")
        if name not in self.components:
            raise KeyError(f"component: no component named {name!r}; "
                           f"have {list(self.components)}")
        sl = self.components[name]
        sub = self.system.systems[name] if self.system is not None and hasattr(self.system, "systems") else None
        segs = None if not self._segments else [
            (a, b, j, _Sliced(sol, sl)) for (a, b, j, sol) in self._segments]
        return HybridArc(self.t, self.j, self.x[:, sl], self.termination, self.message,
                         self.exception, getattr(sub, "components", None), segs, sub)

    def __getitem__(self, name):
        return self.component(name)

    def outputs(self, name=None):
        """The output map evaluated along the arc, shape (N, q).

        ``name`` selects a component of an interconnection.
        """
        if name is not None and hasattr(self.system, "outputs"):
            # through the interconnection: feedthrough outputs see their inputs
            out = self.system.outputs
            return np.array([np.atleast_1d(np.asarray(out(x, t, j)[name], dtype=float))
                             for x, t, j in zip(self.x, self.t, self.j)])
        arc = self.component(name) if name is not None else self
        if arc.system is None:
            raise ValueError("outputs: the arc does not know its system")
        c = arc.system._compile()
        if c.h_u:
            raise ValueError("outputs: this system's output reads its input u, which the "
                             "arc does not know; evaluate it through its interconnection")
        return np.array([np.atleast_1d(np.asarray(c.h(x, t, j, None), dtype=float))
                         for x, t, j in zip(arc.x, arc.t, arc.j)])

    # ----------------------------------------------------------------- I/O
    def save(self, path):
        """Save the samples and termination cause to an ``.npz`` file."""
        comps = {} if not self.components else {
            k: (s.start, s.stop) for k, s in self.components.items()}
        np.savez_compressed(path, t=self.t, j=self.j, x=self.x,
                            termination=np.array(self.termination.name if self.termination else ""),
                            message=np.array(self.message),
                            comp_names=np.array(list(comps), dtype=str),
                            comp_bounds=np.array(list(comps.values()), dtype=np.int64).reshape(-1, 2))

    @classmethod
    def load(cls, path):
        """Load an arc written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as d:
            term = str(d["termination"])
            comps = {str(k): slice(int(a), int(b)) for k, (a, b) in
                     zip(d["comp_names"], d["comp_bounds"])} or None
            return cls(d["t"], d["j"], d["x"], Termination[term] if term else None,
                       str(d["message"]), components=comps)

    def to_pandas(self, names=None):
        """A pandas DataFrame with columns t, j and one per state component.

        Requires the optional ``pandas`` extra.
        """
        try:
            import pandas as pd
        except ImportError as e:  # pragma: no cover
            raise ImportError("to_pandas needs pandas: pip install 'hybridsim[pandas]'") from e
        n = self.state_dim
        if names is None:
            names = [f"x{i}" for i in range(n)]
            if self.components:
                names = [None] * n
                for cname, sl in self.components.items():
                    for k, i in enumerate(range(*sl.indices(n))):
                        names[i] = f"{cname}[{k}]"
        if len(names) != n:
            raise ValueError(f"to_pandas: names must have length {n}, got {len(names)}")
        df = pd.DataFrame(self.x, columns=list(names))
        df.insert(0, "j", self.j)
        df.insert(0, "t", self.t)
        return df


class _Sliced:
    """A dense output restricted to a slice of the state."""

    __slots__ = ("sol", "sl")

    def __init__(self, sol, sl):
        self.sol, self.sl = sol, sl

    def __call__(self, t):
        return np.asarray(self.sol(t))[self.sl]
