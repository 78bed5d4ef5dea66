"""Test configuration: one BLAS thread (the matrices here are tiny; threads
only spin on a shared 2-core machine) and a non-interactive matplotlib."""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
