"""Finite-time state observers from five control papers, built on :mod:`hybridsim`.

Modules
-------
li_sanfelice   H_n, H_c, H_pc resetting observers (Li & Sanfelice)
gramian_delay  fixed-time Gramian observers with one delay (Mazenc & Malisoff, LCSYS 2022)
time_varying   reduced-order finite-time observers (Mazenc, Ahmed & Malisoff, CDC 2018)
dynamic_gain   robust finite-time observer with dynamic gain (Nekhoroshikh et al., CDC 2022)
distributed    finite-time distributed observer over a digraph (Silm et al., SCL 2020)
lmi            the LMIs of the dynamic-gain and distributed designs (cvxpy, optional extra)
"""
