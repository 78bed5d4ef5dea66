"""``python -m observers reproduce [name ...] [--out DIR]``."""
from .reproduce import main

raise SystemExit(main())
