"""``python -m observers reproduce [name ...] [--out DIR]``."""
import os

# the matrices here are tiny: BLAS threads only contend (set before numpy loads)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

from .reproduce import main

raise SystemExit(main())
