"""``python -m hybridsim.arch --out DIR [--quick] [--trials N] [--only AT1,CC1]``,
``python -m hybridsim.arch validate DIR``."""
import sys

from .runner import main

sys.exit(main())
