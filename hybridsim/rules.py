"""The engine's rules, written once: priorities, termination causes, the
jump-or-flow decision, and the thresholds that classify a run's end.

Every integration path (:func:`hybridsim.simulate`, the vectorized batch
integrator, the compiled path) takes its semantics from here; none encodes
them again. The decision functions work on plain bools and ints so that a
compiled path can compile them as they are.
"""
from __future__ import annotations

import enum
import math
import operator
import warnings

import numpy as np

__all__ = ["Termination", "Priority", "Action", "decide", "decide_at_event", "event_outcome",
           "after_jump", "CAUSES", "CODES", "J_MAX_CODE", "ZENO_CODE", "NO_CAUSE",
           "raises", "warns", "finish", "DETAILS", "message",
           "jumps_now", "needs_coin", "dwell_outcome", "is_sticking",
           "sticking_message",
           "zeno_message", "time_scale", "t_max_slack", "event_tolerance", "PRIORITIES", "FAILURES",
           "post_jump_probe", "LOOP_JUMPS", "is_jump_loop", "zeno_short", "ZENO_SHRINK",
           "ZENO_WINDOW", "CHATTER_RTOL", "chatter_step",
           "SimulationWarning", "SimulationError", "MapError", "BatchWarning", "BatchError",
           "finish_batch"]

_EPS = float(np.finfo(float).eps)


class SimulationError(RuntimeError):
    """A run stopped on a failure; ``.arc`` holds the solution computed so far.

    Raised by :func:`hybridsim.simulate` (``throw=True``, the default) when a
    user map raises or breaks its contract; see :class:`MapError`.
    """

    def __init__(self, message, arc=None):
        super().__init__(message)
        self.arc = arc


class MapError(SimulationError, ValueError):
    """A user map raised, or returned something the engine cannot use.

    Chained from the original exception (``__cause__``) where there is one.
    ``map_name``, ``t`` and ``j`` say which map failed and where; ``.arc``
    (set by :func:`hybridsim.simulate`) is the solution up to the failure.
    """

    def __init__(self, message, map_name=None, t=None, j=None, arc=None):
        super().__init__(message, arc)
        self.map_name, self.t, self.j = map_name, t, j


class SimulationWarning(RuntimeWarning):
    """A run ended early on a numerical failure, or looks stiff (see the message)."""


class Termination(enum.Enum):
    """Why a run stopped. ``.message`` is a sentence for the user.

    ``success`` is True for the limits the user set (``T_MAX``, ``J_MAX``);
    ``failure`` is True for causes that mean the computation, not the model,
    went wrong (see README's table of failures).
    """

    T_MAX = "the flow reached t_max"
    J_MAX = "the number of jumps reached j_max"
    NOT_IN_SETS = ("the initial state is in neither C nor D: check x0 against "
                   "flow_set and jump_set")
    LEFT_SETS = ("the state left C and is not in D: the solution cannot be "
                 "continued (check flow_set/jump_set near the final state)")
    NON_FINITE = "the state became non-finite (NaN or inf)"
    BLOWUP = "the state norm exceeded max_norm (finite escape or instability)"
    SOLVER_FAILED = ("the ODE solver failed (step size too small: a stiff system "
                     "needs method='Radau', 'BDF' or 'LSODA'; or a finite escape)")
    MAP_ERROR = ("a user map raised an exception or broke its contract (see "
                 "arc.exception)")
    ZENO = ("Zeno behaviour: jumps accumulate without ordinary time advancing "
            "(consecutive flows too short to resolve)")
    MAX_STEPS = ("the run reached max_steps solver steps (or max_samples stored "
                 "samples) before t_max/j_max: raise the limit or look for "
                 "chattering, stiffness or a too small max_step")
    CANCELED = "the run was interrupted (KeyboardInterrupt); the arc so far is kept"

    @property
    def message(self) -> str:
        return self.value

    @property
    def success(self) -> bool:
        return self in (Termination.T_MAX, Termination.J_MAX)

    @property
    def failure(self) -> bool:
        """The computation failed (as opposed to the model ending or a limit)."""
        return self in FAILURES


#: causes under which ``simulate(throw=True)`` raises or a warning is issued
FAILURES = frozenset({Termination.MAP_ERROR, Termination.NON_FINITE,
                      Termination.SOLVER_FAILED, Termination.BLOWUP})


#: every cause in one order: a compiled kernel reports ``CODES[cause]``, an int
CAUSES = tuple(Termination)
CODES = {cause: i for i, cause in enumerate(CAUSES)}
J_MAX_CODE = CODES[Termination.J_MAX]
ZENO_CODE = CODES[Termination.ZENO]
NO_CAUSE = -1           # the run goes on


def raises(cause, throw):
    """Whether a single run that ended with ``cause`` raises (``throw=True``).

    One policy on every path: a user map that raised or broke its contract
    (``MAP_ERROR``) raises :class:`MapError` with the arc so far; every other
    cause, failures included, returns the arc (see :func:`warns`).
    """
    return bool(throw) and cause is Termination.MAP_ERROR


def warns(cause, warn, message=None):
    """Whether a run that ended with ``cause`` issues a :class:`SimulationWarning`
    (``warn=True``): the numerical failures and ``MAX_STEPS``; and ``J_MAX``
    where its ``message`` carries a detail (a jump loop or chattering, kinds
    ``"loop"`` and ``"chatter"`` of :data:`DETAILS`: the limit was reached,
    but something is wrong)."""
    if not warn or cause is Termination.MAP_ERROR:
        return False
    if cause is Termination.J_MAX:
        return message is not None and message != cause.message
    return cause in FAILURES or cause is Termination.MAX_STEPS


def finish(arc, throw, warn, stacklevel=3):
    """Apply the raise/warn policy to a finished single run; returns the arc.

    Raises
    ------
    MapError
        Where :func:`raises`: ``arc.exception`` (a :class:`MapError` naming
        the map, t and j) with ``.arc`` set to the arc so far.
    """
    import warnings

    cause = arc.termination
    if raises(cause, throw):
        err = arc.exception
        if not isinstance(err, MapError):
            err = MapError(arc.message)
        err.arc = arc
        raise err
    if warns(cause, warn, arc.message):
        warnings.warn(f"{cause.name}: {arc.message} (last sample t={arc.t[-1]:.10g}, "
                      f"j={arc.j[-1]})", SimulationWarning, stacklevel=stacklevel)
    return arc


class Priority(enum.IntEnum):
    """What happens in C ∩ D."""

    JUMPS = 0
    FLOWS = 1
    RANDOM = 2


PRIORITIES = ("jumps", "flows", "random")
_JUMPS, _RANDOM = Priority.JUMPS, Priority.RANDOM     # module constants: quicker to read


class Action(enum.IntEnum):
    """The decision at a point of hybrid time."""

    JUMP = 0
    FLOW = 1
    STOP = 2       # in neither C nor D (NOT_IN_SETS at x0, else LEFT_SETS)


_JUMP, _FLOW, _STOP = Action.JUMP, Action.FLOW, Action.STOP


def jumps_now(in_C, in_D, prio, coin, forced=False):
    """Whether the run jumps here: the priority rule, for bools or bool arrays.

    x jumps when it is in D and one of: the last flow's event forces the jump,
    x is not in C, jumps have priority, or (random priority) the coin says so.
    Written with ``&``, ``|`` and ``==`` so that the same expression serves
    :func:`hybridsim.simulate` (Python bools), the vectorized batch
    integrator (numpy arrays, one entry per trajectory) and a compiled path.

    Examples
    --------
    >>> bool(jumps_now(True, True, Priority.FLOWS, False))
    False
    >>> import numpy as np
    >>> jumps_now(np.array([True, False]), np.array([True, True]), Priority.FLOWS, False)
    array([False,  True])
    """
    return in_D & (forced | (in_C == False) | (prio == _JUMPS)  # noqa: E712
                   | ((prio == _RANDOM) & coin))


def needs_coin(in_C, in_D, prio, forced=False):
    """Where :func:`jumps_now` reads the coin (a seeded run draws one only there)."""
    return (prio == _RANDOM) & in_C & in_D & (forced == False)  # noqa: E712


def dwell_outcome(dwelling, t, deadline, tau):
    """The random priority's choice at a point of C ∩ D under a dwell law.

    A dwell ``tau`` (the time to spend in C ∩ D before jumping) is drawn
    once, at the entry into C ∩ D; inside the dwell (``dwelling``) the run
    jumps once ``t`` reaches its ``deadline`` (the flow is stopped there, as
    at an event). ``tau`` is read only where not ``dwelling``. Returns
    ``(jump, dwelling, deadline)``: the coin of :func:`jumps_now` and the
    dwell's new state. Plain floats and bools, so that a compiled path
    compiles it.

    Examples
    --------
    >>> dwell_outcome(False, 1.0, math.inf, 0.25)     # entry: dwell 0.25
    (False, True, 1.25)
    >>> dwell_outcome(True, 1.25, 1.25, 0.0)          # the dwell has elapsed
    (True, True, 1.25)
    >>> dwell_outcome(False, 1.0, math.inf, 0.0)      # a dwell of 0 jumps at once
    (True, False, inf)
    """
    if dwelling:
        return t >= deadline, True, deadline
    if tau <= 0.0:
        return True, False, math.inf
    return False, True, t + tau


def decide(in_C: bool, in_D: bool, prio: int, coin: bool, forced: bool = False) -> int:
    """Jump, flow or stop at a point where the run must choose.

    Parameters
    ----------
    in_C, in_D : bool
        Membership of the current state.
    prio : int
        A :class:`Priority`.
    coin : bool
        For ``Priority.RANDOM``: True means jump (a fair coin, drawn by the
        caller only where :func:`needs_coin` says it matters).
    forced : bool
        The flow just reached this point by an event whose location decided
        that a jump must happen (the flow cannot continue in C).

    Returns
    -------
    int
        An :class:`Action`: ``JUMP`` where :func:`jumps_now`, else ``FLOW``
        in C, else ``STOP``.

    Examples
    --------
    >>> decide(True, True, Priority.JUMPS, False) == Action.JUMP
    True
    >>> decide(True, True, Priority.FLOWS, False) == Action.FLOW
    True
    >>> decide(False, False, Priority.JUMPS, False) == Action.STOP
    True
    """
    if jumps_now(in_C, in_D, prio, coin, forced):
        return _JUMP
    if in_C:
        return _FLOW
    return _STOP


def decide_at_event(entered_D: bool, in_C_at_event: bool, prio: int, coin: bool) -> int:
    """The decision where a located event ends a flow.

    ``entered_D``: the event is an entry into D (watched under ``jumps`` and
    ``random`` priority). Otherwise the flow is leaving C.

    Returns ``Action.JUMP``, ``Action.FLOW`` (random priority chose to flow on
    in C ∩ D) or ``Action.STOP`` (left C outside D).
    """
    if entered_D:
        if prio == _RANDOM and in_C_at_event and not coin:
            return _FLOW
        return _JUMP
    return _STOP


def event_outcome(watching_D, in_D_hi, in_C_hi, in_D_lo, prio, coin):
    """What a located event does: ``(action, side)``, side 0 the bracket's
    last point before the event (``lo``), 1 its first point after (``hi``).

    The transition every path takes where a flow's event is located in
    ``(lo, hi]``: an entry into D (watched, ``watching_D``) decides at hi
    (:func:`decide_at_event`: jump, or flow on where the random priority's
    ``coin`` says so); else the flow is leaving C: it jumps from lo if lo is
    in D, else from hi if hi is in D, else it stops at lo (outside C ∪ D).
    Plain bools and ints, so that a compiled path compiles it.

    Examples
    --------
    >>> event_outcome(True, True, False, False, Priority.JUMPS, True) == (Action.JUMP, 1)
    True
    >>> event_outcome(False, False, False, False, Priority.JUMPS, True) == (Action.STOP, 0)
    True
    """
    if watching_D and in_D_hi:
        return decide_at_event(True, in_C_hi, prio, coin), 1
    if in_D_lo:
        return _JUMP, 0
    if in_D_hi:
        return _JUMP, 1
    return _STOP, 0


def after_jump(jumps, short, j_max, zeno_jumps):
    """The cause code a jump ends the run with, or :data:`NO_CAUSE`.

    ``jumps``: jumps taken so far (this one included); ``short``:
    consecutive jumps after short flows (:func:`zeno_short`). ``J_MAX``
    comes before ``ZENO``: the user's limit is the reason given.
    """
    if jumps >= j_max:
        return J_MAX_CODE
    if short >= zeno_jumps:
        return ZENO_CODE
    return NO_CAUSE


#: consecutive jumps at one instant, each from a state in C, that make a jump loop
LOOP_JUMPS = 10


def is_jump_loop(count, zeno_jumps):
    """Whether ``count`` consecutive jumps at exactly one instant, each taken
    from a state that is in C as well as in D, are a jump loop.

    Such jumps happen where the priority prefers jumping in C ∩ D and the
    state after the jump is in D again: typically a jump set given by a
    guard alone (D = {guard >= 0} still holds on the guard's zero, where the
    jump map leaves the state), so the run jumps forever without flowing.
    A deliberate cascade of resets at one instant is a handful of jumps;
    ten (or the Zeno test's own count, ``zeno_jumps``, where smaller) is a
    loop. The run still ends by the usual rules (``J_MAX``, then ``ZENO``,
    :func:`after_jump`): only the message changes (kind ``"loop"`` in
    :data:`DETAILS`), saying what is wrong. A purely discrete system (C
    empty) is never a loop: its jumps are not taken from C.
    """
    return count >= min(LOOP_JUMPS, zeno_jumps)


def post_jump_probe(x_plus, lo, x_lo, x_hi):
    """Where C is tested again for a post-jump state that is in neither C nor D.

    The rule: a state ``x_plus`` after a jump from a located event counts
    as in C (the run flows on from ``x_plus`` itself) when the flow set
    holds at the returned ``(t, x)``: ``x_plus`` displaced by the pre-jump
    flow's motion over the event's bracket, ``x_lo - x_hi``, at the
    bracket's start ``lo``.

    Why: an event is located only to its bracket ``(lo, hi]``, of width at
    most :func:`event_tolerance`; the run jumps from ``x_hi``, just past
    the crossing, where ``x_lo`` (not yet at the event) is in C. A jump map
    that keeps the located position (a ball on a moving floor reflecting
    its relative velocity) carries that location error into ``x_plus``:
    up to ``|f| * event_tolerance`` outside C. Had the event been taken
    at ``lo``, equally valid to the tolerance, the post-jump position
    would have been the displaced one. The tolerance is therefore exactly
    the event's own location error, measured along the flow (it needs no
    guard: indicators and guards are treated alike, and no map is
    evaluated but the flow set). A state genuinely outside C, farther
    than the flow moves in ``event_tolerance``, is still outside
    (``LEFT_SETS``). Plain arrays and floats, so that a compiled path
    compiles it.

    Examples
    --------
    >>> import numpy as np
    >>> t, x = post_jump_probe(np.array([-6e-16, 1.0]), 0.5, np.array([3e-16, -2.0]),
    ...                        np.array([-6e-16, -2.0]))
    >>> t, bool(x[0] >= 0)
    (0.5, True)
    """
    return lo, x_plus + (x_lo - x_hi)


def event_tolerance(a: float, b: float) -> float:
    """Width to which an event time is bracketed: 4 ulp of the time scale."""
    return 4.0 * _EPS * max(1.0, abs(a), abs(b))


def t_max_slack(t_max: float, jumps: int = 0) -> float:
    """How far past ``t_max`` an event still counts as happening at ``t_max``.

    Each located event is bracketed to 4 ulp (:func:`event_tolerance`) and
    its time is the bracket's upper end, so jump times drift late by up to
    4 ulp per jump, and the flow's integration adds its own rounding. An
    event that is exactly at t_max in exact arithmetic can therefore land
    beyond it by about that much: events within ``(16 + 2 jumps)`` event
    tolerances of t_max are taken at t_max.

    Examples
    --------
    >>> import numpy as np
    >>> float(t_max_slack(1.0) / np.finfo(float).eps)
    64.0
    """
    return event_tolerance(t_max, t_max) * (16.0 + 2.0 * jumps)


def _max(a, b):
    """max(a, b) for floats and numpy arrays alike (to rounding)."""
    return 0.5 * (a + b + abs(a - b))


#: a flow at most this fraction of the longest of the :data:`ZENO_WINDOW`
#: flows before it continues a shrinking streak (:func:`zeno_short`)
ZENO_SHRINK = 0.9999
#: how many flows before the current one a shrinking streak compares it with
ZENO_WINDOW = 3


def zeno_short(flows, m, t, ref, zeno_time, zeno_rtol):
    """Whether the flow before a jump counts towards Zeno, and the streak's reference.

    Zeno is an accumulation of jumps: flows that shrink, relative to the
    run's own earlier flows, so that their sum converges. The test reads
    only the run's flows, never its horizon: a timer jumping every 1 ms
    for ever is no accumulation, whatever t_max is.

    A flow (of length ``flows[m - 1]``, ending at t) counts (``short``) when

    * it is at most ``zeno_time * max(1, |t|)``: too short to resolve in
      floating point (a jump loop at one instant, chattering at round-off);
      or
    * it lies in a *shrinking streak* and has shrunk to at most
      ``zeno_rtol`` times the streak's reference. A flow continues the
      streak when it is at most :data:`ZENO_SHRINK` times the longest of
      the (up to) :data:`ZENO_WINDOW` flows before it, so the flows
      decrease geometrically (by at least that factor every few jumps,
      which lets two or three modes alternate, as in the two-tank
      system), and their sum converges; the reference ``ref`` is the
      longest flow before the streak began (0: no streak).

    A run ends ``ZENO`` after ``zeno_jumps`` consecutive such flows
    (:func:`after_jump`): the flows a geometric accumulation of ratio r has
    left then sum to about ``zeno_rtol * ref * r**zeno_jumps / (1 - r)``, so
    the run stops at its accumulation time to that accuracy. Flows
    that shrink more slowly than :data:`ZENO_SHRINK` per window count only
    once below the absolute floor.

    ``flows``: the run's last flow lengths, the current one at ``m - 1``
    (the entries before it are read back to :data:`ZENO_WINDOW`); ``ref``:
    the value this function returned at the previous jump (0.0 at the
    first). Returns ``(short, ref)``. Plain floats and a plain loop, so
    that a compiled path compiles it.

    Examples
    --------
    >>> zeno_short([1e-3, 1e-3, 1e-3, 1e-3], 4, 1.0, 0.0, 1e-12, 1e-7)   # a 1 kHz timer
    (False, 0.0)
    >>> zeno_short([1.0, 0.5, 0.25, 2e-8], 4, 2.0, 1.0, 1e-12, 1e-7)     # shrunk 5e7-fold
    (True, 1.0)
    >>> zeno_short([1.0, 1.0, 1.0, 0.0], 4, 2.0, 0.0, 1e-12, 1e-7)[0]    # no flow at all
    True
    """
    flow = flows[m - 1]
    prev = 0.0
    k = m - 1 - ZENO_WINDOW
    if k < 0:
        k = 0
    for i in range(k, m - 1):
        if flows[i] > prev:
            prev = flows[i]
    if prev > 0.0 and flow <= ZENO_SHRINK * prev:
        if not ref > 0.0:
            ref = prev              # the streak begins: its reference flow
    else:
        ref = 0.0
    short = flow <= zeno_time * max(1.0, abs(t)) or (ref > 0.0 and flow <= zeno_rtol * ref)
    return short, ref


#: a flow at most this fraction of the run's longest earlier flow is tiny:
#: consecutive tiny flows up to ``J_MAX`` are chattering (:func:`chatter_step`)
CHATTER_RTOL = 1e-3


def chatter_step(flow, longest, count):
    """Update the chattering count after a jump: ``(longest, count)``.

    ``count`` counts consecutive jumps after a flow at most
    :data:`CHATTER_RTOL` times ``longest``, the longest flow of the run
    before it (a ball that has come to rest on a floor, bouncing every
    10 us after falls of a second). A run that reaches ``j_max`` with the
    last :data:`LOOP_JUMPS` (or ``zeno_jumps``, if fewer) flows tiny is
    chattering (:func:`is_jump_loop`'s threshold): it still ends ``J_MAX``,
    with a message that says so (kind ``"chatter"`` of :data:`DETAILS`; kind
    ``"instant"`` where those jumps were all at one instant but not from C,
    so not a loop of :func:`is_jump_loop`) and one warning (:func:`finish`).
    Plain floats, so that a compiled path compiles it.

    Examples
    --------
    >>> chatter_step(9e-6, 0.45, 3)
    (0.45, 4)
    >>> chatter_step(0.3, 0.45, 4)
    (0.45, 0)
    """
    count = count + 1 if (longest > 0.0 and flow <= CHATTER_RTOL * longest) else 0
    if flow > longest:
        longest = flow
    return longest, count


def is_sticking(last_flows, flow_now, jumps, scale):
    """The run left C outside D after a run of ever shorter flows: sticking.

    A ball coming to rest on a moving floor: its bounces accumulate and the
    flow leaves C with a tiny relative velocity on the wrong side of D. That
    is a Zeno-like end, not a mistake in the sets (``LEFT_SETS``).
    ``last_flows`` are the lengths of the flows before the last jumps (the
    last three are read), ``flow_now`` the length of the flow since the last
    jump. Written as plain loops so that the compiled path compiles it.
    """
    m = len(last_flows)
    if jumps < 3 or m < 3 or not flow_now <= 1e-6 * scale:
        return False
    for k in range(m - 3, m):
        if not last_flows[k] <= 1e-3 * scale:
            return False
    return True


def sticking_message(t, j, x, last_flows):
    """What :func:`is_sticking` found, and what to change."""
    flows = ", ".join(f"{f:.3g}" for f in list(last_flows)[-3:])
    return (f"the flow left C outside D at t={t:.10g} (j={j}) after a run of ever shorter "
            f"flows ({flows}): the solution sticks to the boundary of C (jumps "
            f"accumulate; a Zeno-like end), x={x}. Model the sticking (e.g. a mode where "
            f"the contact persists, or a jump map that stops the motion below a threshold)")


#: the details of each cause, by kind: one table for every path. A run's
#: message is ``cause.message`` followed by ``": "`` and the filled detail
#: (:func:`message`); ``{x}`` is the state as numpy prints it, times with 10
#: significant digits.
DETAILS = {
    (Termination.NOT_IN_SETS, None): "x={x} at (t={t:.10g}, j={j})",
    (Termination.LEFT_SETS, None): "x={x} at (t={t:.10g}, j={j})",
    (Termination.LEFT_SETS, "left"): "the flow left C at t={t:.10g} (j={j}), x={x}, outside D",
    (Termination.ZENO, "short"): "flows too short to resolve near t={t:.10g}",
    # the words the vectorized path prints today (a test compares the two paths)
    (Termination.NON_FINITE, "step"): "after the step from t={t:.10g} to t={t2:.10g} (j={j})",
    (Termination.NON_FINITE, "flow"): "flow_map returned non-finite values near t={t:.10g} (j={j})",
    (Termination.NON_FINITE, "guard"): "{name} returned NaN near t={t:.10g} (j={j})",
    (Termination.BLOWUP, None): "|x| = {norm:.3g} > {max_norm:.3g} at t={t:.10g} (j={j})",
    (Termination.SOLVER_FAILED, None): "{reason} at t={t:.10g} (j={j})",
    (Termination.MAX_STEPS, "steps"): "{steps} solver steps (max_steps={max_steps}) at t={t:.10g}",
    (Termination.MAX_STEPS, "samples"): ("{samples} samples stored (max_samples={max_samples}) "
                                         "at t={t:.10g}"),
    (Termination.CANCELED, None): "stopped at t={t:.10g}, j={j}",
    (Termination.NON_FINITE, "dense"): ("the step's dense output from t={t:.10g} to "
                                        "t={t2:.10g} (j={j}) is non-finite (overflow inside "
                                        "the step)"),
    (Termination.J_MAX, "loop"): ("a jump loop: the last {count} jumps were all at "
                                  "t={t:.10g}, each from a state in C and D (flowing was "
                                  "possible): the state after each jump is still in D. "
                                  "Check jump_set: a jump_guard alone makes "
                                  "D = {{guard >= 0}}, which the state after the jump "
                                  "still satisfies on the guard's zero"),
    (Termination.J_MAX, "chatter"): ("chattering: the last {count} flows were each shorter "
                                     "than {rtol:g} times the run's longest flow "
                                     "({longest:.3g}), the last {flow:.3g} at t={t:.10g}: "
                                     "the solution sticks to the boundary of C or chatters "
                                     "between the sets. Model the contact (a mode where it "
                                     "persists, or a jump map that stops the motion below "
                                     "a threshold), or add hysteresis to the sets"),
    (Termination.J_MAX, "instant"): ("jumps at one instant: the last {count} jumps were all "
                                     "at t={t:.10g}, the state after each still in D. "
                                     "Check jump_set and jump_map: a jump_guard "
                                     "alone makes D = {{guard >= 0}}, which a state left on "
                                     "or just past the guard's zero still satisfies"),
    (Termination.ZENO, "loop"): ("a jump loop: the last {count} jumps were all at "
                                 "t={t:.10g}, each from a state in C and D (flowing was "
                                 "possible): the state after each jump is still in D. "
                                 "Check jump_set: a jump_guard alone makes "
                                 "D = {{guard >= 0}}, which the state after the jump "
                                 "still satisfies on the guard's zero"),
}


def message(cause, kind=None, **fields):
    """A run's message: the cause's sentence and its filled detail.

    ``kind`` picks the detail among :data:`DETAILS` (None: the cause's
    default detail); ``ZENO`` kinds ``"zeno"`` and ``"sticking"`` are filled
    by :func:`zeno_message` and :func:`sticking_message`; ``MAP_ERROR``
    takes ``error`` (the map error's own text). A cause without details
    (``T_MAX``, ``J_MAX``) is its sentence alone.

    Examples
    --------
    >>> message(Termination.CANCELED, t=0.25, j=3)
    'the run was interrupted (KeyboardInterrupt); the arc so far is kept: stopped at t=0.25, j=3'
    """
    if cause is Termination.ZENO and kind == "zeno":
        detail = zeno_message(fields["count"], fields["t"])
    elif cause is Termination.ZENO and kind == "sticking":
        detail = sticking_message(fields["t"], fields["j"], fields["x"], fields["flows"])
    elif cause is Termination.MAP_ERROR:
        detail = fields.get("error")
    else:
        fmt = DETAILS.get((cause, kind))
        detail = None if fmt is None else fmt.format(**fields)
    return cause.message if not detail else f"{cause.message}: {detail}"


def zeno_message(count, t):
    """What the Zeno test found (the same words on every integration path)."""
    return (f"{count} consecutive jumps after flows that shrank geometrically to "
            f"zeno_rtol times the run's earlier flows, or below zeno_time*max(1,|t|) "
            f"(rules.zeno_short), near t={t:.10g}")


def time_scale(t0, t, t_max):
    """The run's time scale for relative tests: its horizon, else the time elapsed.

    ``t`` may be an array (one entry per trajectory of a batch).
    """
    if math.isfinite(t_max) and t_max > t0:
        return t_max - t0
    return _max(t - t0, 0.0)


# ------------------------------------------------------------------ batches
# The batch policy (what fails a row, the one summary warning, throw=True), the
# same on every path: :func:`finish`'s counterpart for a batch.
#: causes that make a row "failed" in a batch (named in the summary warning)
FAILED = frozenset(FAILURES | {Termination.MAX_STEPS})
_SHOW = 5               # failed rows named one by one in the summary


class BatchWarning(SimulationWarning):
    """Some runs of a batch failed or were canceled; the message names the rows.

    Each failed row's arc carries its cause (``arc.termination``,
    ``arc.message``, ``arc.exception``).
    """


class BatchError(SimulationError):
    """A run of a batch failed and the batch was called with ``throw=True``.

    Attributes
    ----------
    row : int
        Index of the failed row (its place in ``x0s`` or ``params``).
    arc : HybridArc
        That row's arc (its cause in ``arc.termination``/``arc.exception``).
    arcs : list of HybridArc or None
        The batch's arcs so far, in row order (None for rows not run).
    """

    def __init__(self, message, row=None, arc=None, arcs=None):
        super().__init__(message, arc)
        self.row, self.arcs = row, arcs


_TERMINATION = operator.attrgetter("termination")


def _summary(what, arcs, offset=0):
    """One warning text for the failed and canceled rows, or None."""
    # by identity (an Enum member hashes in Python code: 0.3 µs a row)
    bad, stop = {id(c) for c in FAILED}, id(Termination.CANCELED)
    terms = list(map(id, map(_TERMINATION, arcs)))
    if bad.isdisjoint(terms) and stop not in terms:     # the common case: one pass
        return None
    failed = [(i, arcs[i]) for i, c in enumerate(terms) if c in bad]
    canceled = [i for i, c in enumerate(terms) if c == stop]
    parts = []
    if failed:
        named = []
        for i, a in failed[:_SHOW]:
            msg = a.message or a.termination.message
            if isinstance(a.exception, SimulationError):      # names the map already
                msg = str(a.exception)
            elif a.exception is not None:
                msg = f"{type(a.exception).__name__}: {a.exception}"
            msg = " ".join(str(msg).split())
            if len(msg) > 160:
                msg = msg[:157] + "..."
            named.append(f"row {i}: {a.termination.name} ({msg})")
        more = f"; and {len(failed) - _SHOW} more" if len(failed) > _SHOW else ""
        parts.append(f"{len(failed)} of {len(arcs)} runs failed: " + "; ".join(named) + more
                     + ". Each failed row's arc carries its cause (arc.termination, "
                       "arc.message, arc.exception); pass throw=True to raise at the first "
                       "failure instead")
    if canceled:
        rows = canceled if len(canceled) <= 2 * _SHOW else \
            [*canceled[:_SHOW], "...", *canceled[-1:]]
        finished = len(arcs) - len(canceled)
        parts.append(f"interrupted (KeyboardInterrupt): {finished} of {len(arcs)} runs finished, "
                     f"rows {', '.join(map(str, rows))} end with CANCELED (the arc so far, or "
                     f"one sample at x0 for rows never started)")
    if not parts:
        return None
    return f"{what}: " + ". ".join(parts) + "."


def _raise_first_failure(out):
    """``throw=True`` on a batch that ran in one piece: the first failed row raises."""
    for i, arc in enumerate(out):
        if arc.termination in FAILED:
            raise BatchError(f"row {i} of the batch failed: {arc.termination.name}: "
                             f"{arc.message}", i, arc, out) from arc.exception


def finish_batch(name, arcs, throw, warn, stacklevel=3):
    """The batch policy, applied once a batch has run: the same on every path.

    Every row has run and every failed row keeps its arc and cause (one of
    :data:`FAILED`). ``throw=True`` raises :class:`BatchError` (``.row``,
    ``.arc``, ``.arcs``) for the first failed row; otherwise ``warn=True``
    issues one :class:`BatchWarning` naming the failed (and canceled) rows.
    Used by :func:`hybridsim.simulate_many`, :func:`hybridsim.simulate_vectorized`
    and the compiled batch (every path imports it from here).

    Parameters
    ----------
    name : str
        The entry point named in the warning (``"simulate_many"``...).
    arcs : list of HybridArc
        One per row, in order.
    throw, warn : bool
    stacklevel : int
        Of the warning: 3 points at the caller of the function that calls
        ``finish_batch``.

    Returns
    -------
    list of HybridArc
        ``arcs``.
    """
    if throw:
        _raise_first_failure(arcs)
    return _warned(name, arcs, warn, stacklevel + 1)


def _warned(name, out, warn, stacklevel=3):
    """One BatchWarning summarising the failed rows (if any and if asked)."""
    if warn:
        msg = _summary(name, out)
        if msg:
            warnings.warn(msg, BatchWarning, stacklevel=stacklevel)
    return out
