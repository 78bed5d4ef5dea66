"""The places of the compiled run kernel's options in its two arrays, ``fopt``
(float64) and ``iopt`` (int64): one list, read by the packer
(:func:`hybridsim.compiled._run._parse_options`) and by the kernel
(:func:`hybridsim.compiled._kernel._run_core`, where numba reads each as a
constant of the compiled code). Needs no numba.

Examples
--------
>>> from hybridsim.compiled import _layout as lay
>>> lay.F_DELAYS == lay.F_ZENO_RTOL + 1 and lay.I_SIZE == lay.I_ROW + 1
True
"""
from __future__ import annotations

# ``fopt``: the run's floats, then the flow map's delays tau_i (``iopt[I_N_DELAYS]``)
F_T0 = 0
F_T_MAX = 1
F_J_MAX = 2
F_RTOL = 3
F_MAX_STEP = 4
F_FIRST_STEP = 5            # NaN: none
F_MAX_NORM = 6
F_ZENO_TIME = 7
F_ZENO_RTOL = 8
F_DELAYS = 9                # the delays from here on

# ``iopt``: the run's integers and the system's flags
I_J0 = 0
I_PRIO = 1                  # int(hybridsim.rules.Priority)
I_MAX_STEPS = 2             # int64's largest: no limit
I_MAX_SAMPLES = 3
I_ZENO_JUMPS = 4
I_REFINE = 5
I_HAS_C = 6                 # a flow set (an indicator or a guard)
I_HAS_D = 7                 # a jump set
I_HAS_HC = 8                # a flow guard
I_HAS_HD = 9                # a jump guard
I_CAP = 10                  # the rows the run's sample buffers start with
I_D_FROM_GUARD = 11         # D is {jump guard >= 0} (no indicator)
I_C_FROM_GUARD = 12         # C is {flow guard >= 0}
I_N_DELAYS = 13
I_ROW = 14                  # 1: a batch kernel's row (its buffers returned uncopied)
I_SIZE = 15
